"""`calibrate --band`: the band is fitted with the thresholds, stored in the manifest, and judges detect,
the live step and the evaluation; memories calibrated without one behave as before."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.calibration.conformal import conformal_threshold
from robofailring.calibration.fusions import conformal_peaks
from robofailring.calibration.job import CalibrateConfig, calibrate, success_scores
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.band import NONE, NORM, SHIFT
from robofailring.detection.config import DetectorConfig
from robofailring.detection.rules import CONTRAST, NOVELTY, PAPER
from robofailring.encoders.placement import EncoderPlacement
from robofailring.evaluation.job import EvaluateConfig, run_evaluation
from robofailring.jobs.detect import DetectConfig, run_detect
from robofailring.memory.recipe import MemoryRecipe

ALPHA = 0.1  # 12 calibration runs allow α ≥ 1/13


def _calibrated(calibration_set: tuple[Path, Path, Path], band: str, folder: Path) -> Path:
    data, memory, cache = calibration_set
    copy = folder / f"memory-{band}"
    copy.mkdir()
    for item in memory.iterdir():
        (copy / item.name).write_bytes(item.read_bytes())
    calibrate(
        CalibrateConfig(
            data=DataSelection(data),
            memory=copy,
            placement=EncoderPlacement(cache_dir=cache),
            threshold_policy=ThresholdPolicy(target_fpr=ALPHA, band=band),
        )
    )
    return copy


def test_the_band_is_fitted_with_the_thresholds_and_stored(
    calibration_set: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, _, cache = calibration_set
    memory_dir = _calibrated(calibration_set, NORM, tmp_path)
    stored = json.loads((memory_dir / "manifest.json").read_text(encoding="utf-8"))["calibration"]
    banded = {name: rule["band"]["kind"] for name, rule in stored["rules"].items() if "band" in rule}
    assert banded == {"contrast": NORM, "novelty": NORM}  # δ stays one number, as in the paper
    assert stored["successes"] == 12  # a whole run count, read back as one
    memory = FailureMemory.load(memory_dir)
    assert memory.manifest.calibration is not None and memory.manifest.calibration.successes == 12
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    detector = FailureDetector(memory, encoder)
    assert set(detector.bands) == {"contrast", "novelty"}  # δ stays one number, as in the paper
    # γ is the conformal threshold of the success runs' peaks, each corrected by the band of the others
    successes = [t for t in load_dataset(data).select(split="train") if not t.is_failure]
    bare = FailureDetector(memory, encoder, delta=0.9, gamma=0.0, eta=0.1)  # given thresholds: no band
    assert bare.bands == {}
    runs = success_scores(bare, successes, [CONTRAST])[CONTRAST]
    peaks, band = conformal_peaks(runs, NORM)
    assert detector.gamma == pytest.approx(conformal_threshold(peaks, ALPHA))
    assert band is not None
    np.testing.assert_allclose(detector.bands["contrast"].mean, band.mean, atol=1e-5)
    np.testing.assert_allclose(detector.bands["contrast"].scale, band.scale, atol=1e-5)


def test_detect_and_the_live_step_fire_where_the_raw_score_crosses_the_line(
    calibration_set: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, _, cache = calibration_set
    memory_dir = _calibrated(calibration_set, NORM, tmp_path)
    detector = FailureDetector(
        FailureMemory.load(memory_dir), CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    )
    fired = 0
    for trajectory in load_dataset(data).select(split="test"):
        trace = detector.run(trajectory)
        line = trace.threshold_line()
        assert trace.band is not None and not np.allclose(line, line[0])  # a line over time
        raw = trace.raw_max_score(CONTRAST)
        crossing = np.flatnonzero(raw >= line)
        assert trace.t_det == (int(crossing[0]) if crossing.size else None)
        fired += trace.t_det is not None
        session = detector.session(trajectory.task)
        for t in range(trace.length):
            step = session.step({view: trajectory.views[view][t] for view in trace.views})
            assert step.threshold == pytest.approx(float(line[t]), abs=1e-6)
            assert step.alarm == bool(trace.state[t])
    assert fired
    shown = run_detect(
        DetectConfig(
            data=DataSelection(data),
            detector=DetectorConfig(memory=memory_dir, placement=EncoderPlacement(cache_dir=cache)),
            key=trajectory.episode,
        )
    )
    as_json = shown.to_dict()
    assert as_json["band"] == NORM and len(as_json["threshold_line"]) == trace.length
    assert "γ_t = μ_t + " in shown.to_text() and "norm band" in shown.to_text()


def test_without_a_band_one_threshold_judges_as_before(
    calibration_set: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, _, cache = calibration_set
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    flat = FailureDetector(FailureMemory.load(_calibrated(calibration_set, NONE, tmp_path)), encoder)
    assert flat.bands == {}
    manifest = json.loads((tmp_path / "memory-none" / "manifest.json").read_text(encoding="utf-8"))
    assert not any("band" in rule for rule in manifest["calibration"]["rules"].values())
    shifted = FailureDetector(FailureMemory.load(_calibrated(calibration_set, SHIFT, tmp_path)), encoder)
    assert shifted.bands["contrast"].kind == SHIFT and np.all(shifted.bands["contrast"].scale == 1.0)
    for trajectory in list(load_dataset(data).select(split="test"))[:4]:
        trace = flat.run(trajectory)
        np.testing.assert_array_equal(trace.threshold_line(), np.full(trace.length, flat.gamma, np.float32))
        assert trace.t_det == trace.view_scores.first_at_or_above(flat.gamma)


def test_the_evaluation_judges_on_the_band_it_calibrates(
    calibration_set: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, _, cache = calibration_set
    results = {
        band: run_evaluation(
            EvaluateConfig(
                data=DataSelection(data),
                threshold_policy=ThresholdPolicy(target_fpr=ALPHA, band=band),
                recipe=MemoryRecipe(encoder="pixels"),
                placement=EncoderPlacement(cache_dir=cache),
                out=tmp_path / band,
            )
        )
        for band in (NONE, NORM)
    }
    assert results[NONE].band == NONE and results[NORM].band == NORM
    assert results[NORM].to_dict()["band"] == NORM and "band `norm`" in results[NORM].to_markdown()
    for key, trace in results[NORM].traces.items():
        judged = results[NORM].rule_trace(key, CONTRAST)
        assert judged.band is not None and trace.bands.keys() == {CONTRAST.name, NOVELTY.name}
    # the paper rule keeps one δ either way, and its tables do not change
    assert results[NORM].rules[PAPER.name].threshold == results[NONE].rules[PAPER.name].threshold
    assert results[NORM].paper_rates == results[NONE].paper_rates


def test_a_bad_band_is_a_usage_error_naming_the_choices(calibration_set: tuple[Path, Path, Path]) -> None:
    data, memory, _ = calibration_set
    result = CliRunner().invoke(app, ["calibrate", str(data), "--memory", str(memory), "--band", "wide"])
    assert result.exit_code == 2
    assert "unknown band 'wide'; choose one of ['none', 'shift', 'norm']" in result.output
