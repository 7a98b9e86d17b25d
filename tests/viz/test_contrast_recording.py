"""Recordings of the contrast rule read back: S⁺, C, γ and the nearest success frame equal the trace."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli
from rrd import blueprint_names, entity_paths, properties, rows, static_value
from synthetic import write_project_dataset

from rfr_viz.paths import REPLAY
from rfr_viz.recordings.replay import record_replay
from rfr_viz.viewer.rrd import verify_recording
from robofailring import (
    CachedEncoder,
    DetectionTrace,
    FailureDetector,
    FailureMemory,
    Trajectory,
    load_dataset,
    load_encoder,
)
from robofailring.calibration.bands import fit_band
from robofailring.data.selection import DataSelection
from robofailring.detection.band import NORM
from robofailring.detection.rules import CONTRAST
from robofailring.encoders.placement import EncoderPlacement
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.recipe import MemoryRecipe
from robofailring.memory.signals.modality import SIGNALS_VIEW


@pytest.fixture(scope="module")
def replayed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Trajectory, DetectionTrace, Path]:
    root = tmp_path_factory.mktemp("contrast-rec")
    data = write_project_dataset(root / "data", tasks=("pick_cube",), episodes=4, length=7)
    memory, _ = build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=root / "memory",
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=root / "c"),
            split="train",
        )
    )
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=root / "c")
    trajectory = next(t for t in load_dataset(data).select(split="test") if t.is_failure)
    first = FailureDetector(memory, encoder, k=2).run(trajectory)
    trace = first.with_rule(CONTRAST, float(np.median(first.max_score())))  # fires part-way
    assert trace.t_det is not None
    return trajectory, trace, record_replay(trajectory, trace, out=root / "replay.rrd")


def test_contrast_entities_equal_the_trace(replayed: tuple[Trajectory, DetectionTrace, Path]) -> None:
    _, trace, recording = replayed
    verify_recording(recording)
    paths = entity_paths(recording)
    for view in trace.views:
        assert {
            REPLAY.success_score(view),
            REPLAY.score(view, "contrast"),
            REPLAY.nearest_success(view),
        } <= paths
        for entity, expected in (
            (REPLAY.score(view, "paper"), trace.similarity[view]),
            (REPLAY.success_score(view), trace.success_similarity[view]),
            (REPLAY.score(view, "contrast"), trace.scores_of(CONTRAST)[view]),
        ):
            logged = rows(recording, entity, "Scalars:scalars")
            assert [frame for frame, _ in logged] == list(range(trace.length))
            np.testing.assert_allclose([value[0] for _, value in logged], expected, atol=1e-6)
        gamma = rows(recording, REPLAY.threshold("contrast"), "Scalars:scalars")
        assert len(gamma) == trace.length
        np.testing.assert_allclose([value[0] for _, value in gamma], trace.gamma, atol=1e-9)
        # the nearest success frame: an image where it changes, its text (episode, frame) every frame
        images = rows(recording, REPLAY.nearest_success(view), "EncodedImage:blob")
        changed = [0] + [
            t for t in range(1, trace.length) if trace.success_ids[view][t] != trace.success_ids[view][t - 1]
        ]
        assert [frame for frame, _ in images] == changed
        texts = rows(recording, REPLAY.nearest_success_info(view), "TextDocument:text")
        assert len(texts) == trace.length
        for t, text in texts:
            match = trace.nearest_success(view, t)
            assert (
                match is not None and match.run.episode in text[0] and f"frame **{match.frame}**" in text[0]
            )
    assert static_value(recording, REPLAY.score(trace.views[0], "contrast"), "SeriesLines:names") == [
        f"{trace.views[0]} {CONTRAST.formula}"
    ]


def test_report_and_properties_say_which_rule_fired(
    replayed: tuple[Trajectory, DetectionTrace, Path],
) -> None:
    _, trace, recording = replayed
    props = properties(recording)
    assert props["score"] == "contrast" and props["threshold"] == pytest.approx(trace.gamma)
    assert props["t_det"] == trace.t_det
    reports = rows(recording, REPLAY.report, "TextDocument:text")
    assert reports[-1][0] == trace.t_det and "Fired by the contrast rule" in reports[-1][1][0]
    top = trace.neighbors(trace.detected_view, trace.t_det)[0].entry  # type: ignore[arg-type]
    assert f"(nearest failure: {top.episode}, {top.moment})" in reports[-1][1][0]
    event = rows(recording, REPLAY.event, "TextLog:text")
    assert event[0][0] == trace.t_det and "(contrast rule): C_t = " in event[0][1][0]


def test_a_banded_threshold_is_drawn_as_the_line_it_is(
    replayed: tuple[Trajectory, DetectionTrace, Path], tmp_path: Path
) -> None:
    trajectory, trace, _ = replayed
    runs = [
        np.linspace(0.2, -0.1, trace.length) + 0.02 * np.sin(np.arange(trace.length) + k) for k in range(12)
    ]
    band = fit_band(NORM, runs)
    banded = replace(trace, bands={CONTRAST.name: band})
    line = banded.threshold_line(CONTRAST)
    assert not np.allclose(line, line[0])
    recording = record_replay(trajectory, banded, out=tmp_path / "banded.rrd")
    gamma = rows(recording, REPLAY.threshold("contrast"), "Scalars:scalars")
    assert [frame for frame, _ in gamma] == list(range(trace.length))
    np.testing.assert_allclose([value[0] for _, value in gamma], line, atol=1e-6)
    assert static_value(recording, REPLAY.threshold("contrast"), "SeriesLines:names") == [
        f"γ_t = μ_t + {trace.gamma:.3f}·σ_t (norm band)"
    ]
    # the plot's title names the line too (its legend is hidden: titles carry the thresholds)
    titles = [name for name in blueprint_names(recording) if "C_t = S⁻_t − S⁺_t" in name]
    assert titles == [f"γ_t = μ_t + {trace.gamma:.3f}·σ_t (norm band) · C_t = S⁻_t − S⁺_t per view"]
    # the detection instant is where the raw contrast first reaches the line
    assert properties(recording)["t_det"] == (-1 if banded.t_det is None else banded.t_det)
    crossing = np.flatnonzero(banded.raw_max_score(CONTRAST) >= line)
    assert banded.t_det == (int(crossing[0]) if crossing.size else None)


def test_the_signals_s_plus_is_recorded_under_the_signals_view(tmp_path: Path) -> None:
    """`replay` of a memory with the robot's signals: their S⁺_t at `/score/signals/success`, equal to the
    trace's, beside their contrast at `/score/signals/contrast` (docs/recording.md)."""
    data = write_project_dataset(
        tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=4, length=6, signals=True
    )
    cache = tmp_path / "c"
    memory = tmp_path / "memory"
    built = cli("build-memory", data, "--out", memory, "--split", "train", "--cache-dir", cache)
    assert built.exit_code == 0, built.output
    episode = "pick_cube_grasp_wp2_episode1"
    out = tmp_path / "replays"
    replayed = cli(
        "replay", data, "--memory", memory, "--trajectory", episode, "--out", out, "--cache-dir", cache
    )
    assert replayed.exit_code == 0, replayed.output
    (recording,) = out.glob(f"*{episode}*.rrd")
    trajectory = next(t for t in load_dataset(data) if t.episode == episode)
    trace = FailureDetector(
        FailureMemory.load(memory), CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    ).run(trajectory)
    assert trace.signals is not None
    logged = rows(recording, REPLAY.success_score(SIGNALS_VIEW), "Scalars:scalars")
    assert [frame for frame, _ in logged] == list(range(trajectory.length))
    np.testing.assert_allclose([value[0] for _, value in logged], trace.signals.success_similarity, atol=1e-6)
    for view in trace.views:  # each camera's S⁺ its own, not the signals'
        camera = rows(recording, REPLAY.success_score(view), "Scalars:scalars")
        np.testing.assert_allclose(
            [value[0] for _, value in camera], trace.success_similarity[view], atol=1e-6
        )
