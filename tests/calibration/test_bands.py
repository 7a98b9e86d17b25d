"""Time-indexed thresholds: the band's per-frame statistic, its leave-one-out fits, the conformal promise
on corrected peaks, and what it stores."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robofailring.calibration.bands import (
    MIN_BAND_RUNS,
    MIN_SCALE,
    SCALE_FLOOR,
    check_band,
    fit_band,
    leave_one_out,
)
from robofailring.calibration.conformal import conformal_threshold
from robofailring.calibration.fusions import conformal_peaks
from robofailring.detection.band import NORM, SHIFT, Band
from robofailring.errors import MemoryFormatError, SettingError

LENGTH = 30
# success runs score high and noisily over the first frames (every run starts alike), then low and calm
PROFILE_MEAN = np.where(np.arange(LENGTH) < 6, 0.5, 0.0)
PROFILE_SPREAD = np.where(np.arange(LENGTH) < 6, 0.3, 0.05)


def _runs(rng: np.random.Generator, count: int, length: int = LENGTH) -> list[np.ndarray]:
    return [
        PROFILE_MEAN[:length] + PROFILE_SPREAD[:length] * rng.standard_normal(length) for _ in range(count)
    ]


def test_the_norm_band_is_the_per_frame_mean_and_spread_of_the_runs() -> None:
    runs = _runs(np.random.default_rng(0), 40)
    band = fit_band(NORM, runs)
    table = np.stack(runs)
    np.testing.assert_allclose(band.mean, table.mean(axis=0), atol=1e-6)
    spread = table.std(axis=0, ddof=1)
    floor = max(SCALE_FLOOR * float(np.median(spread)), MIN_SCALE)
    np.testing.assert_allclose(band.scale, np.maximum(spread, floor), rtol=1e-5)
    assert band.runs == 40 and band.kind == NORM
    shift = fit_band(SHIFT, runs)
    np.testing.assert_allclose(shift.mean, band.mean) and np.testing.assert_array_equal(shift.scale, 1.0)
    # corrected = (score − μ_t)/σ_t; the raw-score line is μ_t + θ·σ_t, so both judge alike
    scores = runs[0]
    corrected = band.correct(scores)
    np.testing.assert_allclose(corrected, (scores - band.mean) / band.scale, rtol=1e-5)
    line = band.line(1.5, LENGTH)
    np.testing.assert_array_equal(corrected >= 1.5, scores >= line)
    assert band.line_at(1.5, 7) == pytest.approx(float(line[7]))


def test_frames_beyond_the_runs_hold_the_last_well_covered_statistic() -> None:
    rng = np.random.default_rng(1)
    runs = _runs(rng, 12, length=20) + _runs(rng, 3, length=LENGTH)  # only 3 runs reach frames 20-29
    band = fit_band(NORM, runs)
    assert len(band.mean) == LENGTH
    np.testing.assert_array_equal(band.mean[20:], band.mean[19])  # fewer than MIN_RUNS: held
    mean, scale = band.statistic(50)
    assert mean[49] == band.mean[-1] and scale[49] == band.scale[-1]
    assert band.correct(np.zeros(50)).shape == (50,)


def test_unscored_frames_are_left_out_of_the_statistic() -> None:
    runs = _runs(np.random.default_rng(2), 20)
    strided = [np.where(np.arange(LENGTH) % 2 == 0, run, np.nan) for run in runs]
    band = fit_band(SHIFT, strided)
    np.testing.assert_allclose(band.mean[::2], np.stack(runs).mean(axis=0)[::2], atol=1e-6)
    np.testing.assert_array_equal(
        band.mean[1::2], band.mean[::2][: LENGTH // 2]
    )  # held from the frame before
    assert np.isnan(band.correct(strided[0])[1])


def test_each_run_is_corrected_by_the_band_of_the_others() -> None:
    runs = _runs(np.random.default_rng(3), 15)
    for row, band in enumerate(leave_one_out(NORM, runs)):
        others = fit_band(NORM, runs[:row] + runs[row + 1 :])
        np.testing.assert_allclose(band.mean, others.mean, atol=1e-6)
        np.testing.assert_allclose(band.scale, others.scale, rtol=1e-4)
        assert band.runs == 14


def test_a_banded_threshold_keeps_the_false_alarm_promise_and_fires_earlier() -> None:
    rng = np.random.default_rng(4)
    alpha, fresh = 0.1, _runs(rng, 2000)
    # failures: calm runs that step up by 0.3 (6 σ of the calm frames, one σ of the first ones) from frame 15
    failures = [run + np.where(np.arange(LENGTH) >= 15, 0.3, 0.0) for run in _runs(rng, 400)]
    realised = {"none": [], NORM: []}
    recall = {"none": [], NORM: []}
    for _ in range(60):
        calibration = _runs(rng, 49)
        for kind in realised:
            peaks, band = conformal_peaks(calibration, kind)
            threshold = conformal_threshold(peaks, alpha)
            judge = (lambda run: run) if band is None else band.correct
            realised[kind].append(np.mean([judge(run).max() >= threshold for run in fresh]))
            recall[kind].append(np.mean([judge(run).max() >= threshold for run in failures]))
    for kind in realised:  # the promise holds on average over calibration sets (within sampling noise)
        assert np.mean(realised[kind]) <= alpha + 0.01, kind
    assert np.mean(recall[NORM]) > 0.9 > 0.5 > np.mean(recall["none"])


def test_too_few_runs_fit_no_band() -> None:
    runs = _runs(np.random.default_rng(5), MIN_BAND_RUNS - 1)
    peaks, band = conformal_peaks(runs, NORM)
    assert band is None and peaks == pytest.approx([float(run.max()) for run in runs])
    _, band = conformal_peaks(_runs(np.random.default_rng(5), MIN_BAND_RUNS), NORM)
    assert band is not None and band.runs == MIN_BAND_RUNS
    # a run with nothing scored (the only success run of its task) has no peak
    peaks, band = conformal_peaks([np.full(LENGTH, np.nan), *_runs(np.random.default_rng(6), 12)], NORM)
    assert np.isnan(peaks[0]) and band is not None and band.runs == 12


def test_bands_are_stored_and_read_back() -> None:
    band = fit_band(NORM, _runs(np.random.default_rng(7), 12))
    read = Band.from_dict(json.loads(json.dumps(band.to_dict())), where="test")
    np.testing.assert_allclose(read.mean, band.mean, atol=1e-6)
    np.testing.assert_allclose(read.scale, band.scale, atol=1e-6)
    assert (read.kind, read.runs) == (NORM, 12)
    for broken in (
        {"kind": NORM, "mean": [0.1], "scale": [0.0], "runs": 3},
        {"kind": NORM, "mean": [0.1, 0.2], "scale": [1.0], "runs": 3},
        {"kind": NORM, "mean": [0.1], "runs": 3},
        {"mean": [0.1], "scale": [1.0], "runs": 3},
        {"kind": "wide", "mean": [0.1], "scale": [1.0], "runs": 3},
        ["not", "a", "band"],
    ):
        with pytest.raises(MemoryFormatError, match="test"):
            Band.from_dict(broken, where="test")


def test_band_settings_are_checked() -> None:
    assert check_band("shift") == SHIFT
    with pytest.raises(SettingError, match=r"unknown band 'wide'; choose one of \['none', 'shift', 'norm'\]"):
        check_band("wide")
    with pytest.raises(SettingError, match="at least 2 calibration runs"):
        fit_band(NORM, [np.zeros(3)])
    with pytest.raises(SettingError, match="no statistic"):
        fit_band("none", [np.zeros(3), np.zeros(3)])
    assert isinstance(fit_band(SHIFT, [np.zeros(3), np.ones(3)]), Band)
