"""robofailring.jobs.closed_loop and its recording (rfr_viz.recordings.closed_loop): the detector stops a simulated robot."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
from environment import viewer_available
from rrd import entity_paths, properties, reader, rows, static_value, values

from rfr_viz.paths import APPLICATION_ID, CLOSED_LOOP_SUMMARY, UNSTOPPED, WATCHED
from rfr_viz.recordings.closed_loop import ClosedLoopResult, run_closed_loop
from rfr_viz.viewer.control import render_screenshot
from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset
from robofailring.jobs.closed_loop import watch_episode
from robofailring.sim import VIEWS, EpisodeResult, GenerateConfig, generate_dataset, run_episode

pytestmark = pytest.mark.slow  # simulation or end-to-end: the full lane only (scripts/test.sh)

TASK, MODE, SEED = "pick_cube", "grasp", 7  # a seed none of the memory's episodes was drawn from
SIZE, FRAMES = 48, 12


@dataclass(frozen=True)
class Reference:
    """The same episode run by hand with a plain session: S_t per view per frame and the goal check."""

    similarity: dict[str, np.ndarray]
    result: EpisodeResult

    @property
    def peak(self) -> np.ndarray:
        """max over views of S_t, per frame."""
        return np.max(np.stack(list(self.similarity.values())), axis=0)


@pytest.fixture(scope="module")
def memory(tmp_path_factory: pytest.TempPathFactory, encoder: CachedEncoder) -> FailureMemory:
    config = GenerateConfig(
        out=tmp_path_factory.mktemp("sim") / "data",
        tasks=(TASK,),
        modes=(MODE,),
        episodes=2,
        image_size=SIZE,
        frames=FRAMES,
        workers=1,
    )
    built, _ = FailureMemory.build(load_dataset(generate_dataset(config)).trajectories(), encoder)
    return built


@pytest.fixture(scope="module")
def reference(memory: FailureMemory, encoder: CachedEncoder) -> Reference:
    session = FailureDetector(memory, encoder).session(TASK)
    scores: dict[str, list[float]] = {}
    with run_episode(TASK, MODE, SEED, image_size=SIZE, frames=FRAMES) as run:
        for images in run:
            for view, similarity in session.step(images).similarity.items():
                scores.setdefault(view, []).append(similarity)
        result = run.run_to_end()
    return Reference({view: np.asarray(values) for view, values in scores.items()}, result)


@pytest.fixture(scope="module")
def stop_frame(reference: Reference) -> int:
    frame = int(np.argmax(reference.peak))
    assert 0 < frame < FRAMES - 1, "the chosen seed must peak mid-episode"
    return frame


@pytest.fixture(scope="module")
def stopped(
    memory: FailureMemory,
    encoder: CachedEncoder,
    reference: Reference,
    stop_frame: int,
    tmp_path_factory: pytest.TempPathFactory,
) -> ClosedLoopResult:
    """δ between the peak S_t and everything before it: the alarm fires exactly at the peak."""
    delta = float(reference.peak[stop_frame] + reference.peak[:stop_frame].max()) / 2
    return run_closed_loop(
        memory=memory,
        encoder=encoder,
        task=TASK,
        mode=MODE,
        seed=SEED,
        out=tmp_path_factory.mktemp("rec") / "closed.rrd",
        delta=delta,
        k=3,
        image_size=SIZE,
        frames=FRAMES,
        recording_id="closed-loop-test",
    )


def test_the_watched_run_stops_at_the_alarm(stopped: ClosedLoopResult, stop_frame: int) -> None:
    assert stopped.stop_frame == stop_frame and stopped.length == FRAMES
    assert stopped.stop_view in VIEWS
    assert stopped.watched.stopped_early and stopped.watched.frames == stop_frame + 1
    assert not stopped.unstopped.stopped_early and stopped.unstopped.frames == FRAMES
    assert len(stopped.watched_steps) == stop_frame + 1 and len(stopped.unstopped_steps) == FRAMES
    assert stopped.saving_ratio == pytest.approx(1 - stop_frame / FRAMES)


def test_outcomes_are_what_the_episode_reported(
    stopped: ClosedLoopResult, reference: Reference, stop_frame: int
) -> None:
    assert stopped.unstopped == reference.result
    with run_episode(TASK, MODE, SEED, image_size=SIZE, frames=FRAMES) as run:
        for t, _ in enumerate(run):
            if t == stop_frame:
                run.stop()
        assert stopped.watched == run.result
    path = stopped.path
    found = properties(path)
    assert found["outcome_watched"] == stopped.watched.outcome
    assert found["outcome_unstopped"] == stopped.unstopped.outcome
    assert found["t_det"] == stop_frame and found["L"] == FRAMES and found["label"] == reference.result.label
    frames, texts = values(path, WATCHED.outcome, "TextLog:text")
    assert frames == [stop_frame] and f"goal check {stopped.watched.outcome.upper()}" in str(texts[0])
    frames, texts = values(path, UNSTOPPED.outcome, "TextLog:text")
    assert frames == [FRAMES - 1] and f"goal check {stopped.unstopped.outcome.upper()}" in str(texts[0])
    summary = static_value(path, CLOSED_LOOP_SUMMARY, "TextDocument:text")[0]
    assert f"STOP at frame {stop_frame}" in summary
    assert f"| watched | {stop_frame + 1}/{FRAMES} (stopped) | **{stopped.watched.outcome}**" in summary


def test_watched_cameras_end_at_the_stop_and_unstopped_run_on(
    stopped: ClosedLoopResult, stop_frame: int
) -> None:
    path = stopped.path
    paths = entity_paths(path)
    assert {WATCHED.camera(v) for v in VIEWS} | {UNSTOPPED.camera(v) for v in VIEWS} <= paths
    read = reader(path)
    (recording,) = read.recordings()
    assert recording.application_id == APPLICATION_ID and recording.recording_id == "closed-loop-test"
    assert read.blueprints(), "the blueprint is saved inside the recording"
    for view in VIEWS:
        watched, blobs = values(path, WATCHED.camera(view), "EncodedImage:blob")
        assert watched == list(range(stop_frame + 1))
        unstopped, _ = values(path, UNSTOPPED.camera(view), "EncodedImage:blob")
        assert unstopped == list(range(FRAMES))
        image = cv2.imdecode(np.frombuffer(bytes(blobs[-1]), np.uint8), cv2.IMREAD_COLOR)
        assert image is not None and image.shape == (SIZE, SIZE, 3)
        frames, labels = values(path, WATCHED.stopped(view), "Points2D:labels")
        assert frames == [stop_frame] and labels == [f"STOPPED at frame {stop_frame}"]
        assert UNSTOPPED.stopped(view) not in paths
    # the robot's signals of both runs: the watched one's end at the stop, the unstopped one's run on
    watched_width = rows(path, WATCHED.signal("gripper_width"), "Scalars:scalars")
    assert [frame for frame, _ in watched_width] == list(range(stop_frame + 1))
    assert [frame for frame, _ in rows(path, UNSTOPPED.signal("action"), "Scalars:scalars")] == list(
        range(FRAMES)
    )
    assert all(0.0 <= width[0] <= 0.081 for _, width in watched_width)


def test_scores_state_and_the_stop_event(
    stopped: ClosedLoopResult, reference: Reference, stop_frame: int
) -> None:
    path = stopped.path
    for view in VIEWS:
        for paths, steps in ((WATCHED, stopped.watched_steps), (UNSTOPPED, stopped.unstopped_steps)):
            frames, scores = values(path, paths.detector.score(view, "paper"), "Scalars:scalars")
            assert frames == list(range(len(steps)))
            np.testing.assert_allclose(scores, [step.similarity[view] for step in steps], atol=1e-6)
            np.testing.assert_allclose(scores, reference.similarity[view][: len(steps)], atol=1e-6)
    _, state = values(path, WATCHED.detector.state, "Scalars:scalars")
    assert state == [0.0] * stop_frame + [1.0]
    _, state = values(path, UNSTOPPED.detector.state, "Scalars:scalars")
    assert state == [float(p >= stopped.delta) for p in reference.peak]
    _, delta = values(path, WATCHED.detector.threshold("paper"), "Scalars:scalars")
    np.testing.assert_allclose(delta, [stopped.delta] * (stop_frame + 1))

    frames, texts = values(path, WATCHED.detector.event, "TextLog:text")
    assert frames == [stop_frame]
    view = stopped.stop_view
    assert view is not None
    top = stopped.watched_steps[stop_frame].neighbors[view][0]
    text = str(texts[0])
    assert text.startswith(f"watched: STOP issued at frame {stop_frame}: view {view}")
    assert (
        f"S_t = {top.similarity:.3f}" in text and top.entry.symbol in text and top.entry.description in text
    )
    frames, texts = values(path, UNSTOPPED.detector.event, "TextLog:text")
    assert frames == [stop_frame] and "not acted on" in str(texts[0])


def test_no_alarm_lets_both_runs_complete(
    memory: FailureMemory, encoder: CachedEncoder, reference: Reference, tmp_path: Path
) -> None:
    result = run_closed_loop(
        memory=memory,
        encoder=encoder,
        task=TASK,
        mode=MODE,
        seed=SEED,
        out=tmp_path / "no_alarm.rrd",
        delta=float(reference.peak.max()) + 0.01,
        image_size=SIZE,
        frames=FRAMES,
    )
    assert result.stop_frame is None and result.stop_view is None and result.saving_ratio is None
    assert result.watched == result.unstopped == reference.result
    for view in VIEWS:
        for paths in (WATCHED, UNSTOPPED):
            assert values(result.path, paths.camera(view), "EncodedImage:blob")[0] == list(range(FRAMES))
    logged = entity_paths(result.path)
    assert WATCHED.detector.event not in logged and UNSTOPPED.detector.event not in logged
    assert not any(entity.endswith("/stopped") for entity in logged)
    assert properties(result.path)["t_det"] == -1
    assert "No alarm" in static_value(result.path, CLOSED_LOOP_SUMMARY, "TextDocument:text")[0]


@pytest.mark.viewer
def test_closed_loop_renders_in_the_real_viewer(
    stopped: ClosedLoopResult, stop_frame: int, tmp_path: Path
) -> None:
    with viewer_available():
        shot = render_screenshot(stopped.path, tmp_path / "closed.png", frame=stop_frame)
    assert shot.errors == [], shot.errors
    image = cv2.imread(str(shot.path), cv2.IMREAD_COLOR)
    assert image is not None and image.shape[1] >= 1280 and float(image.std()) > 20.0
    # the red STOPPED frames around the watched cameras are on screen
    red = (image[:, :, 2] > 200) & (image[:, :, 1] < 90) & (image[:, :, 0] < 90)
    assert int(red.sum()) > 300


def test_the_library_control_loop_stops_the_robot_without_rerun(
    memory: FailureMemory, encoder: CachedEncoder, stopped: ClosedLoopResult, stop_frame: int
) -> None:
    """robofailring.jobs.closed_loop on its own: the same stop, frames and goal checks as the recording's run."""
    detector = FailureDetector(memory, encoder, delta=stopped.delta, k=3)
    loop = watch_episode(detector, TASK, MODE, SEED, image_size=SIZE, frames=FRAMES)
    assert loop.stop_frame == stop_frame == stopped.stop_frame
    assert loop.stop_view == stopped.stop_view
    assert loop.saving_ratio == pytest.approx(1 - stop_frame / FRAMES)
    assert [len(frames) for frames in loop.watched.frames.values()] == [stop_frame + 1] * len(VIEWS)
    assert [len(frames) for frames in loop.unstopped.frames.values()] == [FRAMES] * len(VIEWS)
    assert loop.watched.size == (SIZE, SIZE)
    assert loop.watched.result == stopped.watched and loop.unstopped.result == stopped.unstopped
    assert [step.similarity for step in loop.unstopped.steps] == [
        step.similarity for step in stopped.unstopped_steps
    ]
    assert f"**STOP at frame {stop_frame}**" in loop.summary()
