"""Time-indexed thresholds fitted (functional conformal prediction, as FAIL-Detect does): a band per frame index.

A rule's score at frame t of a normal run is not the same at every t: the first frames of every run
match the memories closely, a grasp looks more like a failure than a reach. A single threshold has
to sit above the noisiest moment of every success run, so it is late everywhere else. A band
corrects the score by a statistic of the calibration successes' scores at the same frame index t
(which a live run knows): `shift` subtracts their mean μ_t, `norm` also divides by their spread
σ_t. The peak of the corrected score is then calibrated split-conformally
(`robofailring.calibration.conformal`), each calibration run corrected by a band fitted on the other
runs (`leave_one_out`), so a new success run fires with probability ≤ α as before. On the raw score
the threshold becomes the time-varying line μ_t + θ·σ_t, which recordings draw.

Beyond the longest calibration run, or where fewer than `MIN_RUNS` runs reach a frame index, the
statistic of the last well-covered frame is held. σ_t is floored at `SCALE_FLOOR` × its median
(and `MIN_SCALE`), so a frame where every run scores alike does not turn noise into alarms. With
fewer than `MIN_BAND_RUNS` calibration runs no band is fitted (calibration says so).

Scope: by default (`pooled`) one band is fitted over every task's calibration runs. With `task`, a task with
at least `MIN_BAND_RUNS` calibration runs has a band of its own (`Band.tasks`), fitted on its runs alone, so
one task's early contrast does not shift another's; the other tasks keep the pooled band. A view's band may
have tasks of its own too (the robot's signals under `per-modality` fusion,
`robofailring.calibration.fusions`). A run is judged by its task's bands (`Band.for_task`).

The fitted `Band` is the value the detector applies (`robofailring.detection.band`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import numpy as np

from robofailring.detection.band import NONE, NORM, SHIFT, Band
from robofailring.errors import SettingError

BAND_KINDS: Final[tuple[str, ...]] = (NONE, SHIFT, NORM)
POOLED: Final[str] = "pooled"  # one band over every task's calibration runs
TASK: Final[str] = "task"  # a band per task where it has MIN_BAND_RUNS calibration runs, else the pooled one
BAND_SCOPES: Final[tuple[str, ...]] = (POOLED, TASK)
DEFAULT_BAND_SCOPE: Final[str] = POOLED
DEFAULT_BAND: Final[str] = SHIFT  # the benchmark's best (docs/rules.md, "Time-indexed thresholds")
MIN_RUNS: Final[int] = 5  # calibration runs a frame index needs for its own statistic
MIN_BAND_RUNS: Final[int] = 10  # fewer calibration runs fit no band: the threshold stays one number
SCALE_FLOOR: Final[float] = 0.25  # σ_t ≥ this share of the median σ …
MIN_SCALE: Final[float] = 1e-3  # … and ≥ this (scores are cosines or their differences)


def check_band(kind: str) -> str:
    """A band kind (`none`, `shift`, `norm`); SettingError naming the choices otherwise."""
    if kind not in BAND_KINDS:
        raise SettingError(f"unknown band {kind!r}; choose one of {list(BAND_KINDS)}")
    return kind


def check_band_scope(scope: str) -> str:
    """A band scope (`pooled`, `task`); SettingError naming the choices otherwise."""
    if scope not in BAND_SCOPES:
        raise SettingError(f"unknown band scope {scope!r}; choose one of {list(BAND_SCOPES)}")
    return scope


def _stacked(runs: Sequence[np.ndarray]) -> np.ndarray:
    """(n, T) scores, NaN where a run has no finite score (unscored, shorter, or nothing to compare)."""
    length = max(len(run) for run in runs)
    table = np.full((len(runs), length), np.nan, dtype=np.float64)
    for row, run in enumerate(runs):
        values = np.asarray(run, dtype=np.float64)
        table[row, : len(values)] = np.where(np.isfinite(values), values, np.nan)
    return table


def _held(values: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """`values` where `covered`, else the last covered value (the first covered one before it)."""
    index = np.where(covered, np.arange(len(values)), -1)
    index = np.maximum.accumulate(index)
    first = int(np.flatnonzero(covered)[0])
    return values[np.where(index < 0, first, index)]


def _statistic(
    count: np.ndarray, total: np.ndarray, squares: np.ndarray, kind: str
) -> tuple[np.ndarray, np.ndarray]:
    covered = count >= min(MIN_RUNS, int(count.max()))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / count
        variance = np.maximum(squares / count - mean**2, 0.0) * count / np.maximum(count - 1, 1)
    mean = _held(mean, covered)
    if kind == SHIFT:
        return mean, np.ones_like(mean)
    scale = _held(np.sqrt(variance), covered)
    floor = max(SCALE_FLOOR * float(np.median(scale)), MIN_SCALE)
    return mean, np.maximum(scale, floor)


def fit_band(kind: str, runs: Sequence[np.ndarray]) -> Band:
    """The band of `kind` (`shift` or `norm`) fitted on calibration runs' per-frame scores."""
    bands = _fit(kind, runs, leave_one_out=False)
    return bands[0]


def leave_one_out(kind: str, runs: Sequence[np.ndarray]) -> list[Band]:
    """For each run, the band fitted on all the other runs (what that run's conformal score is corrected by)."""
    return _fit(kind, runs, leave_one_out=True)


def _fit(kind: str, runs: Sequence[np.ndarray], *, leave_one_out: bool) -> list[Band]:
    check_band(kind)
    if kind == NONE:
        raise SettingError("the band 'none' has no statistic to fit")
    if len(runs) < 2:
        raise SettingError(f"a band needs at least 2 calibration runs, got {len(runs)}")
    table = _stacked(runs)
    finite = np.isfinite(table)
    values = np.where(finite, table, 0.0)
    count, total, squares = finite.sum(axis=0), values.sum(axis=0), (values**2).sum(axis=0)
    if not count.any():
        raise SettingError("no calibration run has a finite score to fit a band on")
    if not leave_one_out:
        mean, scale = _statistic(count, total, squares, kind)
        return [Band(kind, mean.astype(np.float32), scale.astype(np.float32), len(runs))]
    bands = []
    for row in range(len(runs)):
        others = count - finite[row]
        if not others.any():
            raise SettingError("a band needs calibration runs with finite scores besides each one")
        mean, scale = _statistic(others, total - values[row], squares - values[row] ** 2, kind)
        bands.append(Band(kind, mean.astype(np.float32), scale.astype(np.float32), len(runs) - 1))
    return bands
