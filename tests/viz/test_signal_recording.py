"""A replay with the robot's signals under fusion `per-modality`, read back (issue 50): the signals' score is
drawn against the signals' own threshold line (their band), not the cameras', and their S⁺ is at the signals'
own entity."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rrd import rows
from synthetic import write_project_dataset

from rfr_viz.paths import REPLAY
from rfr_viz.recordings.replay import record_replay
from robofailring import CachedEncoder, DetectionTrace, FailureDetector, load_dataset, load_encoder
from robofailring.calibration.bands import MIN_BAND_RUNS
from robofailring.detection.band import SHIFT, Band
from robofailring.detection.rules import CONTRAST
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.signals.modality import SIGNALS_VIEW

LENGTH = 8


@pytest.fixture(scope="module")
def replayed(tmp_path_factory: pytest.TempPathFactory) -> tuple[DetectionTrace, Path]:
    root = tmp_path_factory.mktemp("signal-rec")
    data = write_project_dataset(
        root / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=4, length=LENGTH, signals=True
    )
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=root / "cache")
    loaded = load_dataset(data)
    memory, _ = build_memories(
        loaded.select(split="train"), encoder, provenance=Provenance(data=data, encoder="pixels")
    )
    # the bands a per-modality calibration stores: the cameras' (the band itself) and the signals' own
    cameras = Band(SHIFT, np.full(LENGTH, 0.01, np.float32), np.ones(LENGTH, np.float32), MIN_BAND_RUNS)
    signals = Band(SHIFT, np.linspace(0.2, 0.4, LENGTH, dtype=np.float32), np.ones(LENGTH, np.float32), 12)
    band = Band(cameras.kind, cameras.mean, cameras.scale, cameras.runs, views={SIGNALS_VIEW: signals})
    detector = FailureDetector(memory, encoder, k=2, rule=CONTRAST, gamma=0.05, bands={CONTRAST.name: band})
    trajectory = next(t for t in loaded.select(split="test") if t.is_failure)
    trace = detector.run(trajectory)
    assert trace.signals is not None and SIGNALS_VIEW in trace.scored_views
    return trace, record_replay(trajectory, trace, out=root / "replay.rrd")


def test_the_signals_score_is_drawn_against_the_signals_own_threshold(
    replayed: tuple[DetectionTrace, Path],
) -> None:
    trace, recording = replayed
    own = rows(recording, REPLAY.view_threshold("contrast", SIGNALS_VIEW), "Scalars:scalars")
    assert [frame for frame, _ in own] == list(range(LENGTH))
    expected = trace.threshold_line(CONTRAST, SIGNALS_VIEW)
    np.testing.assert_allclose([value[0] for _, value in own], expected, atol=1e-6)
    np.testing.assert_allclose(expected, np.linspace(0.2, 0.4, LENGTH) + 0.05, atol=1e-6)  # μ_t + γ
    cameras = [value[0] for _, value in rows(recording, REPLAY.threshold("contrast"), "Scalars:scalars")]
    np.testing.assert_allclose(cameras, 0.01 + 0.05, atol=1e-6)  # the cameras' line stays the cameras'
    for view in trace.views:  # the cameras have no line of their own
        assert not rows(recording, REPLAY.view_threshold("contrast", view), "Scalars:scalars")


def test_the_signals_success_similarity_is_logged_at_the_signals_entity(
    replayed: tuple[DetectionTrace, Path],
) -> None:
    trace, recording = replayed
    assert trace.signals is not None
    logged = rows(recording, REPLAY.success_score(SIGNALS_VIEW), "Scalars:scalars")
    expected = trace.signals.success_similarity
    scored = np.flatnonzero(np.isfinite(expected))
    assert [frame for frame, _ in logged] == scored.tolist() and len(scored) == LENGTH
    np.testing.assert_allclose([value[0] for _, value in logged], expected[scored], atol=1e-6)
