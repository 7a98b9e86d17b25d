"""Time-indexed thresholds (functional conformal prediction, as FAIL-Detect does): a band per frame index.

A rule's score at frame t of a normal run is not the same at every t: the first frames of every run
match the memories closely, a grasp looks more like a failure than a reach. A single threshold has
to sit above the noisiest moment of every success run, so it is late everywhere else. A band
corrects the score by a statistic of the calibration successes' scores at the same frame index t
(which a live run knows): `shift` subtracts their mean μ_t, `norm` also divides by their spread
σ_t. The peak of the corrected score is then calibrated split-conformally
(`robofailring.detection.conformal`), each calibration run corrected by a band fitted on the other
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
`robofailring.detection.view_bands`). A run is judged by its task's bands (`Band.for_task`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Final

import numpy as np

from robofailring.errors import MemoryFormatError, SettingError

NONE: Final[str] = "none"
SHIFT: Final[str] = "shift"
NORM: Final[str] = "norm"
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


@dataclass(frozen=True)
class Band:
    """One rule's per-frame-index statistic: corrected = (score − mean_t) / scale_t."""

    kind: str  # `shift` or `norm`
    mean: np.ndarray  # (T,) μ_t
    scale: np.ndarray  # (T,) σ_t (ones for `shift`)
    runs: int  # calibration runs it was fitted on
    # per view, its own band (fusion `per-view`, robofailring.detection.view_bands); a view not named here
    # (none, for fusion `max`) is corrected by this band, fitted on the max over views
    views: dict[str, Band] = field(default_factory=dict)
    # per task, its own band (scope `task`), itself with its views; a task not named here is judged by this one
    tasks: dict[str, Band] = field(default_factory=dict)

    def for_task(self, task: str | None) -> Band:
        """The band that judges a run of `task`: its own, else this one, each of its views' likewise (no
        per-task bands left in it)."""
        own = self.tasks.get(task) if task is not None else None
        base = own if own is not None else self
        views = {view: band.for_task(task) for view, band in base.views.items()}
        if not base.tasks and all(views[view] is band for view, band in base.views.items()):
            return base
        return replace(base, tasks={}, views=views)

    def of(self, view: str | None) -> Band:
        """The band that corrects `view`'s score: its own, else this one."""
        return self.views.get(view, self) if view is not None else self

    def _at(self, values: np.ndarray, frames: np.ndarray) -> np.ndarray:
        return values[np.minimum(frames, len(values) - 1)]

    def statistic(self, length: int) -> tuple[np.ndarray, np.ndarray]:
        """(μ_t, σ_t) for frames 0 … length−1, the last value held beyond the calibration runs."""
        frames = np.arange(length)
        return self._at(self.mean, frames), self._at(self.scale, frames)

    def correct(self, scores: np.ndarray, view: str | None = None) -> np.ndarray:
        """The corrected score of frames 0 … L−1 (NaN stays NaN); `scores` is (L,) or (L, …), of `view`."""
        if view in self.views:
            return self.views[view].correct(scores)
        scores = np.asarray(scores, dtype=np.float32)
        mean, scale = self.statistic(len(scores))
        shape = (len(scores),) + (1,) * (scores.ndim - 1)
        return ((scores - mean.reshape(shape)) / scale.reshape(shape)).astype(np.float32)

    def line(self, threshold: float, length: int, view: str | None = None) -> np.ndarray:
        """The threshold on `view`'s raw score at frames 0 … length−1: μ_t + θ·σ_t."""
        mean, scale = self.of(view).statistic(length)
        return (mean + threshold * scale).astype(np.float32)

    def line_at(self, threshold: float, t: int, view: str | None = None) -> float:
        """μ_t + θ·σ_t of `view` at one frame index (a live step)."""
        band = self.of(view)
        frame = min(t, len(band.mean) - 1)
        return float(band.mean[frame] + threshold * band.scale[frame])

    def label(self, symbol: str, threshold: float) -> str:
        """The threshold as the line it is on the raw score: `γ_t = μ_t + 1.230·σ_t (norm band)`."""
        spread = "·σ_t" if self.kind == NORM else ""
        own = ", each view its own" if self.views else ""
        own += f", {len(self.tasks)} tasks their own" if self.tasks else ""
        return f"{symbol}_t = μ_t + {threshold:.3f}{spread} ({self.kind} band{own})"

    def to_dict(self) -> dict[str, Any]:
        """The band as a rule's stored calibration keeps it (`calibration.rules[<rule>].band`)."""
        own = {"views": {view: band.to_dict() for view, band in self.views.items()}} if self.views else {}
        if self.tasks:
            own["tasks"] = {task: band.to_dict() for task, band in self.tasks.items()}
        return {
            "kind": self.kind,
            "runs": self.runs,
            "mean": [round(float(v), 6) for v in self.mean],
            "scale": [round(float(v), 6) for v in self.scale],
        } | own

    @classmethod
    def from_dict(cls, section: Any, *, where: str) -> Band:
        """A band as `to_dict` stored it; MemoryFormatError naming `where` when it is not one."""
        try:
            kind = section["kind"]
            mean = np.asarray(section["mean"], dtype=np.float32)
            scale = np.asarray(section["scale"], dtype=np.float32)
            runs = section["runs"]
        except (KeyError, TypeError, ValueError) as error:
            raise MemoryFormatError(
                f"{where}: a band needs 'kind', 'mean', 'scale' and 'runs' ({error})"
            ) from None
        if (
            kind not in (SHIFT, NORM)
            or mean.ndim != 1
            or mean.shape != scale.shape
            or not len(mean)
            or not np.isfinite(mean).all()
            or not (scale > 0).all()
            or not isinstance(runs, int)
        ):
            raise MemoryFormatError(
                f"{where}: a {kind!r} band needs equal-length finite 'mean' and positive 'scale' lists and a "
                "whole 'runs'; run `robofailring calibrate` again"
            )
        views = section.get("views") or {}
        if not isinstance(views, dict):
            raise MemoryFormatError(
                f"{where}: a band's 'views' must be an object by view name, not {views!r}"
            )
        own = {view: cls.from_dict(band, where=f"{where}, view {view!r}") for view, band in views.items()}
        tasks = section.get("tasks") or {}
        if not isinstance(tasks, dict):
            raise MemoryFormatError(
                f"{where}: a band's 'tasks' must be an object by task name, not {tasks!r}"
            )
        by_task = {task: cls.from_dict(band, where=f"{where}, task {task!r}") for task, band in tasks.items()}
        return cls(kind=kind, mean=mean, scale=scale, runs=runs, views=own, tasks=by_task)


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
