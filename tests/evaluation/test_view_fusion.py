"""`calibrate --fusion per-view` and `evaluate --fusion per-view`: a band per view, fitted with the
thresholds, stored in the manifest, judging detect, the live step and the evaluation alike."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring import (
    CachedEncoder,
    FailureDetector,
    FailureMemory,
    MemoryRecipe,
    load_dataset,
    load_encoder,
)
from robofailring.calibration.bands import TASK
from robofailring.calibration.conformal import conformal_threshold
from robofailring.calibration.fusions import (
    FUSIONS,
    MAX,
    PER_MODALITY,
    PER_VIEW,
    Fusion,
    max_peaks,
    per_modality_peaks,
    per_view_peaks,
)
from robofailring.calibration.job import CalibrateConfig, calibrate, success_view_scores
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.band import SHIFT, Band
from robofailring.detection.rules import CONTRAST, PAPER
from robofailring.encoders.placement import EncoderPlacement
from robofailring.evaluation.job import EvaluateConfig, run_evaluation

ALPHA = 0.1  # 12 calibration runs allow α ≥ 1/13


def _copy(memory: Path, folder: Path) -> Path:
    folder.mkdir()
    for item in memory.iterdir():
        (folder / item.name).write_bytes(item.read_bytes())
    return folder


def test_per_view_bands_are_calibrated_stored_and_judge_detect_and_the_live_step(
    calibration_set: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, memory, cache = calibration_set
    calibrated = _copy(memory, tmp_path / "memory")
    calibrate(
        CalibrateConfig(
            data=DataSelection(data),
            memory=calibrated,
            placement=EncoderPlacement(cache_dir=cache),
            threshold_policy=ThresholdPolicy(target_fpr=ALPHA, band=SHIFT, fusion=PER_VIEW),
        )
    )
    stored = json.loads((calibrated / "manifest.json").read_text(encoding="utf-8"))["calibration"]
    loaded = FailureMemory.load(calibrated)
    views = set(loaded.manifest.views or [])
    assert len(views) >= 2 and set(stored["rules"]["contrast"]["band"]["views"]) == views
    assert "band" not in stored["rules"][PAPER.name]  # δ stays one number
    assert stored["method"] == "split conformal, own episode left out, a band per view"
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    detector = FailureDetector(loaded, encoder)
    # γ is the conformal threshold of the runs' peaks, each view corrected by the band of the other runs
    successes = [t for t in load_dataset(data).select(split="train") if not t.is_failure]
    bare = FailureDetector(loaded, encoder, delta=0.9, gamma=0.0, eta=0.1)
    runs = success_view_scores(bare, successes, [CONTRAST])[CONTRAST]
    peaks, band = per_view_peaks(runs, SHIFT)
    assert band is not None and detector.gamma == pytest.approx(conformal_threshold(peaks, ALPHA))
    for view in views:
        np.testing.assert_allclose(
            detector.bands["contrast"].views[view].mean, band.views[view].mean, atol=1e-5
        )
    fired = 0
    for trajectory in load_dataset(data).select(split="test"):
        trace = detector.run(trajectory)
        raw = trace.scores_of(CONTRAST)
        crossings = [
            np.flatnonzero(raw[view] >= trace.threshold_line(view=view)) for view in trace.views
        ]  # each view against its own line
        first = min((int(c[0]) for c in crossings if c.size), default=None)
        assert trace.t_det == first
        fired += first is not None
        session = detector.session(trajectory.task)
        for t in range(trace.length):
            step = session.step({view: trajectory.views[view][t] for view in trace.views})
            assert step.alarm == bool(trace.state[t])
            if step.alarm and t == trace.t_det:
                assert step.detected_view == trace.detected_view
    assert fired


def test_the_evaluation_calibrates_and_judges_with_the_fusion_it_is_given(
    calibration_set: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, _, cache = calibration_set
    results = {
        fusion: run_evaluation(
            EvaluateConfig(
                data=DataSelection(data),
                threshold_policy=ThresholdPolicy(target_fpr=ALPHA, fusion=fusion),
                out=tmp_path / fusion,
                recipe=MemoryRecipe("pixels"),
                placement=EncoderPlacement(cache_dir=cache),
            )
        )
        for fusion in (MAX, PER_VIEW)
    }
    for key, trace in results[PER_VIEW].traces.items():
        band = results[PER_VIEW].rule_trace(key, CONTRAST).band
        assert band is not None and set(band.views) == set(trace.views)
        assert results[MAX].rule_trace(key, CONTRAST).band.views == {}  # type: ignore[union-attr]
    assert results[PER_VIEW].rules[PAPER.name].threshold == results[MAX].rules[PAPER.name].threshold


def test_fusion_on_the_command_line(calibration_set: tuple[Path, Path, Path], tmp_path: Path) -> None:
    data, memory, _ = calibration_set
    bad = CliRunner().invoke(app, ["calibrate", str(data), "--memory", str(memory), "--fusion", "mean"])
    assert bad.exit_code == 2
    assert "unknown view fusion 'mean'; choose one of ['max', 'per-view', 'per-modality']" in bad.output
    copy = _copy(memory, tmp_path / "memory")
    good = CliRunner().invoke(
        app,
        ["calibrate", str(data), "--memory", str(copy), "--target-fpr", str(ALPHA), "--fusion", "per-view"],
    )
    assert good.exit_code == 0, good.output
    stored = json.loads((copy / "manifest.json").read_text(encoding="utf-8"))["calibration"]["rules"]
    assert "views" in stored["contrast"]["band"]


def test_a_band_per_task_and_modality_is_stored_and_judges_the_trace_and_the_live_step(
    calibration_set: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, memory, cache = calibration_set
    calibrated = _copy(memory, tmp_path / "memory")
    calibrate(
        CalibrateConfig(
            data=DataSelection(data),
            memory=calibrated,
            placement=EncoderPlacement(cache_dir=cache),
            threshold_policy=ThresholdPolicy(
                target_fpr=ALPHA, band=SHIFT, fusion=PER_MODALITY, band_scope=TASK
            ),
        )
    )
    stored = json.loads((calibrated / "manifest.json").read_text(encoding="utf-8"))["calibration"]
    assert stored["method"] == (
        "split conformal, own episode left out, a band per modality (the cameras', and the signals' per task), "
        "a band per task with enough runs"
    )
    assert set(stored["rules"]["contrast"]["band"]["tasks"]) == {"pick_cube"}  # its 12 runs are enough
    loaded = FailureMemory.load(calibrated)
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    detector = FailureDetector(loaded, encoder)
    own = detector.bands["contrast"].for_task("pick_cube")
    successes = [t for t in load_dataset(data).select(split="train") if not t.is_failure]
    bare = FailureDetector(loaded, encoder, delta=0.9, gamma=0.0, eta=0.1)
    runs = success_view_scores(bare, successes, [CONTRAST])[CONTRAST]
    peaks, band = per_modality_peaks(runs, SHIFT)  # one task: its own band is the one over all its runs
    assert band is not None and detector.gamma == pytest.approx(conformal_threshold(peaks, ALPHA))
    np.testing.assert_allclose(own.mean, band.mean, atol=1e-5)
    trajectory = next(t for t in load_dataset(data).select(split="test") if t.is_failure)
    trace = detector.run(trajectory)
    assert trace.band is not None and trace.band.tasks == {}
    np.testing.assert_allclose(trace.band.mean, own.mean)
    session = detector.session(trajectory.task)
    for t in range(trace.length):
        session.step({view: trajectory.views[view][t] for view in trace.views})
        for view in trace.views:
            assert detector.threshold_at(CONTRAST, t, view, task=trajectory.task) == pytest.approx(
                float(trace.threshold_line(view=view)[t]), abs=1e-6
            )


class HalfMax(Fusion):
    """A fusion no other module names: the max over views, its peaks halved."""

    name = "half-max"
    bands = "one band, halved"
    help = "half-max, the max over views at half its height"

    def peaks(
        self, runs: Sequence[Mapping[str, np.ndarray]], kind: str, tasks: Sequence[str] = ()
    ) -> tuple[list[float], Band | None]:
        peaks, band = max_peaks(runs, kind, tasks)
        return [0.5 * value for value in peaks], band


def test_a_new_fusion_is_one_class_in_the_registry(
    calibration_set: tuple[Path, Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Calibration asks the fusion for its peaks and its bands' words: a fusion added to `FUSIONS` is taken
    by a `ThresholdPolicy`, calibrated with, stored and summarised without a line elsewhere."""
    monkeypatch.setitem(FUSIONS, HalfMax.name, HalfMax())
    data, memory, cache = calibration_set
    folders = {fusion: _copy(memory, tmp_path / fusion) for fusion in (MAX, HalfMax.name)}
    found = {
        fusion: calibrate(
            CalibrateConfig(
                data=DataSelection(data),
                memory=folder,
                placement=EncoderPlacement(cache_dir=cache),
                threshold_policy=ThresholdPolicy(target_fpr=ALPHA, band=SHIFT, fusion=fusion),
            )
        )
        for fusion, folder in folders.items()
    }
    halved, full = found[HalfMax.name], found[MAX]
    assert list(halved.thresholds) == list(full.thresholds) == ["paper", "contrast", "novelty"]
    for rule, threshold in full.thresholds.items():
        assert halved.thresholds[rule] == pytest.approx(0.5 * threshold, abs=1e-6)
    assert halved.fusion == HalfMax.name and halved.band == SHIFT
    methods = {
        fusion: json.loads((folder / "manifest.json").read_text(encoding="utf-8"))["calibration"]["method"]
        for fusion, folder in folders.items()
    }
    assert methods == {
        MAX: "split conformal, own episode left out",
        HalfMax.name: "split conformal, own episode left out, one band, halved",
    }
    assert "; one band, halved (fusion half-max)" in halved.to_text(folders[HalfMax.name])
    assert "(fusion" not in full.to_text(folders[MAX])
