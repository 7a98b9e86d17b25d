"""The robot's signals as a second modality in the detector (issue 41 item 3): scored as the view
`signals`, fused with the cameras, the same in a whole run and in live steps, and explained in the
report by the dimensions furthest from the normal runs."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from synthetic import robot_signals, synthetic_frame, write_project_dataset

from robofailring import CachedEncoder, FailureDetector, FailureMemory, Trajectory, load_dataset, load_encoder
from robofailring.data.model import Frame
from robofailring.detection.rules import CONTRAST, PAPER
from robofailring.explain.report import report_for
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.signals.modality import SIGNALS_VIEW

LENGTH = 8


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[FailureMemory, list[Trajectory]]:
    """A memory of the train half and the test half, every run's cameras showing one and the same scene:
    only the robot's signals tell a failure from a success."""
    root = write_project_dataset(
        tmp_path_factory.mktemp("signal-detection") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2", "slip_wp3"),
        episodes=6,
        length=LENGTH,
        signals=True,
    )
    blind = [replace(t, views=_same_scene(t)) for t in load_dataset(root).trajectories()]
    encoder = CachedEncoder(load_encoder("pixels"), enabled=False)
    train = [t for t in blind if t.split == "train"]
    memory, _ = build_memories(train, encoder, provenance=Provenance(data=root, encoder="pixels"))
    return memory, [t for t in blind if t.split == "test"]


def _same_scene(trajectory: Trajectory) -> dict[str, list[Frame]]:
    """Every run's cameras show a success's scene."""
    return {
        view: [Frame.from_array(synthetic_frame("pick_cube", None, number, t, LENGTH)) for t in range(LENGTH)]
        for number, view in enumerate(trajectory.views)
    }


def _detector(memory: FailureMemory, **thresholds: float) -> FailureDetector:
    return FailureDetector(
        memory, CachedEncoder(load_encoder("pixels"), enabled=False), rule=CONTRAST, **thresholds
    )


def test_signals_tell_failures_from_successes_where_the_cameras_cannot(
    runs: tuple[FailureMemory, list[Trajectory]],
) -> None:
    memory, test = runs
    detector = _detector(memory, gamma=0.05)
    for trajectory in test:
        trace = detector.run(trajectory)
        assert trace.scored_views == [*trajectory.views, SIGNALS_VIEW]
        scores = trace.scores_of(CONTRAST)
        cameras = np.nanmax([scores[view] for view in trajectory.views], axis=0)
        signal = scores[SIGNALS_VIEW]
        late = slice(LENGTH // 2, LENGTH)  # after the gripper closed (on the cube, or on nothing)
        if trajectory.is_failure:
            assert np.nanmax(signal[late]) > 0.05 and trace.detected_view == SIGNALS_VIEW
            assert trace.t_det is not None and trace.t_det >= LENGTH // 2
        else:
            # no nearer a failure than a normal run (before closing, failures without an onset look normal)
            assert np.nanmax(signal) < 0.05 and trace.t_det is None
        assert np.nanmax(cameras) < 1e-6  # the cameras see the same scene in every run: S⁻ = S⁺ at best


def test_a_live_session_given_the_signals_scores_what_a_whole_run_does(
    runs: tuple[FailureMemory, list[Trajectory]],
) -> None:
    memory, test = runs
    detector = _detector(memory)
    trajectory = next(t for t in test if t.is_failure)
    trace = detector.run(trajectory)
    values, _ = trajectory.read_signals()
    session = detector.session(trajectory.task)
    for t in range(trajectory.length):
        step = session.step(
            {view: frames[t] for view, frames in trajectory.views.items()},
            signals={name: found.values[t] for name, found in values.items()},
        )
        assert step.similarity[SIGNALS_VIEW] == pytest.approx(float(trace.signals.similarity[t]), abs=1e-5)
        assert step.score[SIGNALS_VIEW] == pytest.approx(float(trace.scores[SIGNALS_VIEW][t]), abs=1e-5)
    assert session.fired_at == trace.t_det
    with pytest.raises(Exception, match=r"signals= lacks 'action'"):
        detector.session(trajectory.task).step(
            {view: frames[0] for view, frames in trajectory.views.items()}, signals={"gripper_width": [0.08]}
        )


def test_the_report_names_the_signal_dimensions_furthest_from_normal(
    runs: tuple[FailureMemory, list[Trajectory]],
) -> None:
    memory, test = runs
    trajectory = next(t for t in test if t.symbol == "grasp_wp2")
    trace = _detector(memory, gamma=0.05).run(trajectory)
    report = report_for(trace, trajectory)
    assert report is not None and report.view == SIGNALS_VIEW and report.signals is not None
    assert report.items  # the camera scoring highest gives the images the VLM is shown
    # the grasp closed on nothing: the width fell further, in one frame and since the start, than in any success
    assert "furthest from normal: gripper_width/width (change over the last frame) -" in report.signals
    assert "gripper_width/width (change since the start) -" in report.signals
    assert "nearest failure: pick_cube_grasp_wp2_episode" in report.signals
    assert "Robot signals:" in report.to_markdown() and report.to_dict()["signals"] == report.signals


def test_a_run_without_the_signals_is_judged_by_its_cameras_and_says_so(
    runs: tuple[FailureMemory, list[Trajectory]],
) -> None:
    memory, test = runs
    bare = replace(test[0], signals={})  # camera-only data: nothing of it is missing (issue 50), it is noted
    trace = _detector(memory).run(bare)
    assert trace.signals is None and trace.scored_views == list(bare.views)
    assert trace.cameras_alone and not [s for s in trace.skipped_inputs if s.view == SIGNALS_VIEW]
    partial = replace(test[0], signals={n: s for n, s in test[0].signals.items() if n != "gripper_width"})
    trace = _detector(memory).run(partial)  # a run lacking one of the memory's signals: listed as not scored
    assert trace.signals is None and not trace.cameras_alone
    (skipped,) = [s for s in trace.skipped_inputs if s.view == SIGNALS_VIEW]
    assert (
        "signals not scored (cameras alone)" in skipped.reason
        and "no signal 'gripper_width'" in skipped.reason
    )
    with_paper = FailureDetector(memory, CachedEncoder(load_encoder("pixels"), enabled=False), rule=PAPER)
    assert SIGNALS_VIEW in with_paper.run(test[0]).scores  # every rule fuses the signals


def test_robot_signals_fixture_is_what_the_dataset_holds(
    runs: tuple[FailureMemory, list[Trajectory]],
) -> None:
    _, test = runs
    trajectory = test[0]
    values, _ = trajectory.read_signals()
    episode = int(trajectory.episode.rsplit("episode", 1)[1])
    expected = robot_signals(trajectory.symbol, LENGTH, episode)
    np.testing.assert_allclose(values["gripper_width"].values, expected["gripper_width"])


def test_the_modality_chooses_what_is_fused(runs: tuple[FailureMemory, list[Trajectory]]) -> None:
    memory, test = runs
    failure = next(t for t in test if t.symbol == "grasp_wp2")
    encoder = CachedEncoder(load_encoder("pixels"), enabled=False)
    by = {
        modality: FailureDetector(memory, encoder, rule=CONTRAST, gamma=0.05, modality=modality).run(failure)
        for modality in ("both", "cameras", "signals")
    }
    assert by["cameras"].scored_views == list(failure.views) and by["cameras"].t_det is None  # blind cameras
    assert by["signals"].scored_views == [SIGNALS_VIEW] and by["signals"].t_det == by["both"].t_det
    # what the evaluation and calibration fuse is the modality's views only
    assert list(by["signals"].scores_of(CONTRAST)) == [SIGNALS_VIEW]
    assert list(by["cameras"].scores_of(CONTRAST)) == list(failure.views)
    assert list(by["both"].scores_of(CONTRAST)) == [*failure.views, SIGNALS_VIEW]
    session = FailureDetector(memory, encoder, rule=CONTRAST, gamma=0.05, modality="cameras").session(
        "pick_cube"
    )
    values, _ = failure.read_signals()
    last = None
    for t in range(failure.length):
        last = session.step(
            {view: frames[t] for view, frames in failure.views.items()},
            signals={name: found.values[t] for name, found in values.items()},
        )
    assert last is not None and SIGNALS_VIEW not in last.score and session.fired_at is None
    with pytest.raises(Exception, match="--modality must be one of both, cameras, signals"):
        FailureDetector(memory, encoder, modality="sound")
