"""`per-view` fusion: each view corrected by a band of its own calibration scores before the max;
`per-modality`: the camera views by one band of their max, the robot's signals by their own."""

from __future__ import annotations

import numpy as np
import pytest

from robofailring.calibration.bands import MIN_BAND_RUNS, check_band_scope, fit_band, leave_one_out
from robofailring.calibration.conformal import auc
from robofailring.calibration.fusions import (
    PeaksOf,
    check_fusion,
    fused_raw,
    max_peaks,
    peak,
    per_modality_peaks,
    per_task_peaks,
    per_view_peaks,
)
from robofailring.detection.band import NONE, NORM, SHIFT, Band
from robofailring.detection.view_scores import ViewScores
from robofailring.errors import MemoryFormatError, SettingError
from robofailring.memory.signals.modality import SIGNALS_VIEW

LENGTH = 12


def _run(rng: np.random.Generator, *, failure: bool) -> dict[str, np.ndarray]:
    """`hand` sees the failure (a late rise of 0.3); `base` never does but sits high and varies a lot
    from run to run (a fixed camera on a scene laid out afresh)."""
    hand = rng.normal(0.05, 0.01, LENGTH)
    if failure:
        hand[LENGTH // 2 :] += 0.3
    base = rng.normal(rng.uniform(0.2, 0.6), 0.02, LENGTH)
    return {"hand": hand.astype(np.float32), "base": base.astype(np.float32)}


def test_each_view_is_corrected_by_the_band_of_the_other_runs_of_that_view() -> None:
    rng = np.random.default_rng(0)
    runs = [_run(rng, failure=False) for _ in range(MIN_BAND_RUNS + 2)]
    runs[3]["base"][:2] = np.nan  # unscored frames stay unscored
    peaks, band = per_view_peaks(runs, SHIFT)
    assert band is not None and set(band.views) == {"hand", "base"}
    assert band.runs == len(runs) and band.views["hand"].runs == len(runs)
    np.testing.assert_allclose(band.views["hand"].mean, fit_band(SHIFT, [r["hand"] for r in runs]).mean)
    np.testing.assert_allclose(band.mean, fit_band(SHIFT, [fused_raw(r) for r in runs]).mean)  # the fallback
    hand_others = leave_one_out(SHIFT, [r["hand"] for r in runs])[3]
    base_others = leave_one_out(SHIFT, [r["base"] for r in runs])[3]
    corrected = {"hand": hand_others.correct(runs[3]["hand"]), "base": base_others.correct(runs[3]["base"])}
    assert peaks[3] == pytest.approx(peak(fused_raw(corrected)), abs=1e-6)


def test_a_view_that_is_high_everywhere_no_longer_hides_the_view_that_sees_the_failure() -> None:
    rng = np.random.default_rng(1)
    calibration = [_run(rng, failure=False) for _ in range(30)]
    tests = [(_run(rng, failure=f), f) for f in [True] * 20 + [False] * 20]
    _, raw_band = per_view_peaks(calibration, NONE)  # nothing corrected: the max over views
    assert raw_band is None
    _, band = per_view_peaks(calibration, SHIFT)
    assert band is not None
    by = {
        "max": [peak(fused_raw(run)) for run, _ in tests],
        "per-view": [peak(fused_raw({v: band.correct(s, v) for v, s in run.items()})) for run, _ in tests],
    }
    failed = [f for _, f in tests]
    scores = {
        name: auc(
            [p for p, f in zip(peaks, failed, strict=True) if f],
            [p for p, f in zip(peaks, failed, strict=True) if not f],
        )
        for name, peaks in by.items()
    }
    assert scores["max"] < 0.8 and scores["per-view"] == 1.0


def test_too_few_runs_or_no_band_keep_the_max_over_views() -> None:
    rng = np.random.default_rng(2)
    runs = [_run(rng, failure=False) for _ in range(MIN_BAND_RUNS - 1)]
    peaks, band = per_view_peaks(runs, NORM)
    assert band is None and peaks == [peak(fused_raw(r)) for r in runs]
    runs += [_run(rng, failure=False) for _ in range(3)]
    runs[0] = {"hand": np.full(LENGTH, np.nan, np.float32), "base": np.full(LENGTH, np.nan, np.float32)}
    peaks, band = per_view_peaks(runs, NORM)
    assert band is not None and np.isnan(peaks[0]) and np.isfinite(peaks[1:]).all()


def test_a_view_with_too_few_calibration_runs_is_corrected_by_the_band_of_the_max() -> None:
    rng = np.random.default_rng(3)
    runs = [_run(rng, failure=False) for _ in range(MIN_BAND_RUNS + 1)]
    for run in runs[:3]:
        run["wrist"] = run["hand"] + 0.1
    _, band = per_view_peaks(runs, SHIFT)
    assert band is not None and set(band.views) == {"hand", "base"}
    values = runs[0]["wrist"]
    np.testing.assert_array_equal(band.correct(values, "wrist"), band.correct(values))
    assert band.of("wrist") is band and band.of("hand") is band.views["hand"]


def test_a_band_with_views_is_stored_and_read_back() -> None:
    rng = np.random.default_rng(4)
    _, band = per_view_peaks([_run(rng, failure=False) for _ in range(MIN_BAND_RUNS)], NORM)
    assert band is not None
    stored = band.to_dict()
    assert set(stored["views"]) == {"hand", "base"} and "views" not in stored["views"]["hand"]
    read = Band.from_dict(stored, where="test")
    for view in ("hand", "base", None):
        np.testing.assert_allclose(read.line(0.5, LENGTH, view), band.line(0.5, LENGTH, view), atol=1e-5)
        assert read.line_at(0.5, 3, view) == pytest.approx(float(band.line(0.5, LENGTH, view)[3]), abs=1e-5)
    assert "each view its own" in band.label("γ", 0.5)
    plain = fit_band(SHIFT, [np.zeros(LENGTH, np.float32), np.ones(LENGTH, np.float32)])
    assert "views" not in plain.to_dict() and Band.from_dict(plain.to_dict(), where="t").views == {}
    with pytest.raises(MemoryFormatError, match="view 'hand'"):
        Band.from_dict({**stored, "views": {"hand": {"kind": "shift"}}}, where="test")


def test_a_live_step_judges_each_view_against_its_own_threshold() -> None:
    scores = ViewScores({"hand": np.array([0.3]), "base": np.array([0.5])}, 1)
    assert scores.firing(0.4, 0) == ["base"] and scores.strongest(0.4, 0) == "base"
    lines = {"hand": 0.2, "base": 0.45}
    assert scores.firing(lines, 0) == ["hand", "base"]
    assert scores.strongest(lines, 0) == "hand"  # furthest over its own line
    assert scores.firing({"hand": 0.35, "base": 0.6}, 0) == []


def test_an_unknown_fusion_is_a_setting_error_naming_the_choices() -> None:
    with pytest.raises(
        SettingError, match=r"unknown view fusion 'mean'; choose one of \['max', 'per-view', 'per-modality'\]"
    ):
        check_fusion("mean")


def _with_signals(rng: np.random.Generator, *, failure: bool) -> dict[str, np.ndarray]:
    """`hand` and `base` as in `_run`, and `signals` whose normal runs score well above the hand camera's
    (a larger contrast on successes) and do not see this failure."""
    signals = rng.normal(rng.uniform(0.35, 0.55), 0.01, LENGTH)
    return _run(rng, failure=failure) | {SIGNALS_VIEW: signals.astype(np.float32)}


def test_per_modality_the_cameras_share_one_band_and_the_signals_have_their_own() -> None:
    rng = np.random.default_rng(5)
    runs = [_with_signals(rng, failure=False) for _ in range(MIN_BAND_RUNS + 2)]
    peaks, band = per_modality_peaks(runs, SHIFT)
    assert band is not None and set(band.views) == {SIGNALS_VIEW} and band.runs == len(runs)
    cameras = [fused_raw({v: r[v] for v in ("hand", "base")}) for r in runs]
    np.testing.assert_allclose(band.mean, fit_band(SHIFT, cameras).mean)
    np.testing.assert_allclose(
        band.views[SIGNALS_VIEW].mean, fit_band(SHIFT, [r[SIGNALS_VIEW] for r in runs]).mean
    )
    assert band.of("hand") is band and band.of("base") is band  # every camera view: the cameras' band
    camera_others = leave_one_out(SHIFT, cameras)[4]
    signal_others = leave_one_out(SHIFT, [r[SIGNALS_VIEW] for r in runs])[4]
    expected = max(
        peak(camera_others.correct(cameras[4])), peak(signal_others.correct(runs[4][SIGNALS_VIEW]))
    )
    assert peaks[4] == pytest.approx(expected, abs=1e-6)
    stored = Band.from_dict(band.to_dict(), where="test")
    np.testing.assert_allclose(
        stored.line(0.1, LENGTH, SIGNALS_VIEW), band.line(0.1, LENGTH, SIGNALS_VIEW), atol=1e-5
    )
    np.testing.assert_allclose(stored.line(0.1, LENGTH, "hand"), band.line(0.1, LENGTH), atol=1e-5)


def test_per_modality_signals_loud_on_successes_no_longer_hide_what_the_cameras_see() -> None:
    rng = np.random.default_rng(6)

    def hand_and_signals(failure: bool) -> dict[str, np.ndarray]:
        return {v: s for v, s in _with_signals(rng, failure=failure).items() if v != "base"}

    calibration = [hand_and_signals(False) for _ in range(30)]
    tests = [(hand_and_signals(f), f) for f in [True] * 20 + [False] * 20]
    _, one = per_modality_peaks(calibration, NONE)
    assert one is None
    fused = [fused_raw(r) for r in calibration]
    max_band = fit_band(SHIFT, fused)
    _, band = per_modality_peaks(calibration, SHIFT)
    assert band is not None
    # the max's band is the signals' (they score highest on the successes): it buries the hand camera's rise
    by = {
        "max": [peak(max_band.correct(fused_raw(run))) for run, _ in tests],
        "per-modality": [
            peak(fused_raw({v: band.correct(s, v) for v, s in run.items()})) for run, _ in tests
        ],
    }
    failed = [f for _, f in tests]
    scores = {
        name: auc(
            [p for p, f in zip(peaks, failed, strict=True) if f],
            [p for p, f in zip(peaks, failed, strict=True) if not f],
        )
        for name, peaks in by.items()
    }
    assert scores["per-modality"] == 1.0 and scores["max"] < 0.8, scores


def test_per_modality_without_signals_is_the_max_and_too_few_runs_correct_nothing() -> None:
    rng = np.random.default_rng(7)
    runs = [_run(rng, failure=False) for _ in range(MIN_BAND_RUNS + 1)]
    peaks, band = per_modality_peaks(runs, SHIFT)
    max_peaks = [
        peak(b.correct(fused_raw(r)))
        for b, r in zip(leave_one_out(SHIFT, [fused_raw(r) for r in runs]), runs, strict=True)
    ]
    assert band is not None and band.views == {}
    np.testing.assert_allclose(peaks, max_peaks, atol=1e-6)
    few = [_with_signals(rng, failure=False) for _ in range(MIN_BAND_RUNS - 1)]
    peaks, band = per_modality_peaks(few, SHIFT)
    assert band is None and peaks == [peak(fused_raw(r)) for r in few]


def test_band_scope_task_fits_a_band_per_task_with_enough_runs_and_the_pooled_one_for_the_rest() -> None:
    rng = np.random.default_rng(8)
    runs = [_run(rng, failure=False) for _ in range(2 * MIN_BAND_RUNS + 3)]
    for run in runs[:MIN_BAND_RUNS]:  # the first task's early frames score high on its successes
        run["hand"][:3] += 0.2
    tasks = ["early"] * MIN_BAND_RUNS + ["plain"] * MIN_BAND_RUNS + ["few"] * 3
    pooled_peaks, pooled = per_view_peaks(runs, SHIFT)
    peaks, band = per_task_peaks(per_view_peaks, runs, tasks, SHIFT)
    assert band is not None and pooled is not None and set(band.tasks) == {"early", "plain"}
    early_peaks, early = per_view_peaks(runs[:MIN_BAND_RUNS], SHIFT)
    assert early is not None
    np.testing.assert_allclose(peaks[:MIN_BAND_RUNS], early_peaks)  # corrected by their own task's others
    np.testing.assert_allclose(peaks[-3:], pooled_peaks[-3:])  # too few runs: corrected as over all tasks
    np.testing.assert_allclose(band.for_task("early").views["hand"].mean, early.views["hand"].mean)
    assert band.for_task("early").views["hand"].mean[0] > band.views["hand"].mean[0] + 0.05
    judged = band.for_task("few")  # a task without its own band, or none named: the pooled band
    assert judged.tasks == {} and band.for_task(None).tasks == {}
    np.testing.assert_allclose(judged.line(0.1, LENGTH, "hand"), pooled.line(0.1, LENGTH, "hand"))
    read = Band.from_dict(band.to_dict(), where="test")
    assert set(read.tasks) == {"early", "plain"} and "each view its own, 2 tasks their own" in band.label(
        "γ", 0.1
    )
    np.testing.assert_allclose(
        read.for_task("early").line(0.1, LENGTH, "hand"),
        band.for_task("early").line(0.1, LENGTH, "hand"),
        atol=1e-5,
    )
    with pytest.raises(MemoryFormatError, match="task 'early'"):
        Band.from_dict({**band.to_dict(), "tasks": {"early": {"kind": "shift"}}}, where="test")
    assert per_task_peaks(per_view_peaks, runs[:5], tasks[:5], SHIFT)[1] is None  # too few runs: no band
    with pytest.raises(SettingError, match=r"unknown band scope 'run'; choose one of \['pooled', 'task'\]"):
        check_band_scope("run")


def test_per_modality_fits_the_signals_a_band_per_task_with_enough_runs() -> None:
    rng = np.random.default_rng(9)
    runs = [_with_signals(rng, failure=False) for _ in range(2 * MIN_BAND_RUNS + 2)]
    for run in runs[:MIN_BAND_RUNS]:  # the first task's signals score high early on its successes
        run[SIGNALS_VIEW][:3] += 0.3
    tasks = ["early"] * MIN_BAND_RUNS + ["plain"] * MIN_BAND_RUNS + ["few"] * 2
    peaks, band = per_modality_peaks(runs, SHIFT, tasks)
    assert band is not None and band.tasks == {}  # the cameras' band is one over all tasks
    signals = band.views[SIGNALS_VIEW]
    assert set(signals.tasks) == {"early", "plain"}
    early = [r[SIGNALS_VIEW] for r in runs[:MIN_BAND_RUNS]]
    np.testing.assert_allclose(signals.tasks["early"].mean, fit_band(SHIFT, early).mean)
    cameras = [fused_raw({v: r[v] for v in ("hand", "base")}) for r in runs]
    camera_others = leave_one_out(SHIFT, cameras)[2]
    expected = max(
        peak(camera_others.correct(cameras[2])), peak(leave_one_out(SHIFT, early)[2].correct(early[2]))
    )
    assert peaks[2] == pytest.approx(expected, abs=1e-6)  # its signals corrected by its task's other runs
    judged = band.for_task("early")  # a run is judged by its task's signal band and the cameras' band
    assert judged.views[SIGNALS_VIEW].tasks == {} and judged.mean is band.mean
    np.testing.assert_allclose(
        judged.line(0.1, LENGTH, SIGNALS_VIEW), signals.tasks["early"].line(0.1, LENGTH)
    )
    np.testing.assert_allclose(
        band.for_task("few").line(0.1, LENGTH, SIGNALS_VIEW), signals.line(0.1, LENGTH)
    )
    assert band.for_task("few").views[SIGNALS_VIEW].tasks == {}
    read = Band.from_dict(band.to_dict(), where="test")
    np.testing.assert_allclose(
        read.for_task("early").line(0.1, LENGTH, SIGNALS_VIEW),
        judged.line(0.1, LENGTH, SIGNALS_VIEW),
        atol=1e-5,
    )


# docs/rules.md: "A band needs at least 10 calibration runs" (a task's own band too, docs/signals.md)
DOCUMENTED_BAND_RUNS = 10


@pytest.mark.parametrize("fusion_peaks", [max_peaks, per_view_peaks], ids=["max", "per-view"])
def test_a_task_one_run_short_of_ten_has_no_band_of_its_own(fusion_peaks: PeaksOf) -> None:
    """Scope `task`: a task with 10 calibration runs gets its own band; one with 9 (or 6) is judged by the
    pooled band, as is each of its runs, the bound the docs give (not only far below it)."""
    rng = np.random.default_rng(11)
    counts = {"ten": DOCUMENTED_BAND_RUNS, "nine": DOCUMENTED_BAND_RUNS - 1, "six": 6}
    tasks = [task for task, count in counts.items() for _ in range(count)]
    runs = [_run(rng, failure=False) for _ in tasks]
    pooled_peaks, _ = fusion_peaks(runs, SHIFT, tasks)
    peaks, band = per_task_peaks(fusion_peaks, runs, tasks, SHIFT)
    assert band is not None and set(band.tasks) == {"ten"}
    assert band.tasks["ten"].runs == DOCUMENTED_BAND_RUNS
    short = [i for i, task in enumerate(tasks) if task != "ten"]
    np.testing.assert_allclose([peaks[i] for i in short], [pooled_peaks[i] for i in short])


def test_the_signals_of_a_task_one_run_short_of_ten_have_no_band_of_their_own() -> None:
    rng = np.random.default_rng(12)
    counts = {"ten": DOCUMENTED_BAND_RUNS, "nine": DOCUMENTED_BAND_RUNS - 1, "six": 6}
    tasks = [task for task, count in counts.items() for _ in range(count)]
    runs = [_with_signals(rng, failure=False) for _ in tasks]
    _, band = per_modality_peaks(runs, SHIFT, tasks)
    assert band is not None and set(band.views[SIGNALS_VIEW].tasks) == {"ten"}
    assert band.views[SIGNALS_VIEW].tasks["ten"].runs == DOCUMENTED_BAND_RUNS
    assert MIN_BAND_RUNS == DOCUMENTED_BAND_RUNS
