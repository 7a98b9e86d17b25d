"""How the views' scores meet one threshold: the fusion a rule is calibrated and judged with.

- `max` (the paper's eq. 7): a view fires when its score reaches the threshold; with a
  time-indexed band (`robofailring.calibration.bands`) one band, fitted on the calibration runs' max over
  views, corrects every view.
- `per-view`: each view's score is corrected by a band fitted on that view's own calibration scores
  before the max. A view whose normal runs score high everywhere (a fixed camera that sees a 4 cm cube
  as a few pixels, in a scene laid out afresh every run) then no longer sets the threshold for the
  view that carries the failure (the hand camera): each view is judged against what is normal for it.
  It needs no failure runs, only the success runs calibration already replays. A view with fewer than
  `MIN_BAND_RUNS` scored calibration runs is corrected by the band of the max over views.
- `per-modality` (the default): the camera views share one band, fitted on their max, and the robot's signals (the view
  `signals`) have their own. Signals whose normal runs score higher than the cameras' (their contrast is
  larger on the calibration successes) then no longer raise the band the cameras are corrected by, which
  under `max` hid failures only the cameras saw; the camera views keep judging each other as under `max`.
  The signals' band is fitted per task where the task has `MIN_BAND_RUNS` calibration runs (the signal memory
  is built per task: its normalisation, layout and derived features are the task's own, and so is when its
  normal runs score high), the cameras' over all tasks (one encoder sees every task).
  A modality with fewer than `MIN_BAND_RUNS` scored calibration runs is corrected by the band of the max
  over views; without signals it is `max`.

Calibration with `per-view` or `per-modality` is split conformal as with `max` (`robofailring.calibration.job`):
each calibration run's views are corrected by bands fitted on the other runs, its peak over frames of
the max over views is its conformal score; the band of all runs, one per view, is stored with the
threshold (`Band.views`; under `per-modality` the cameras' band is the band itself and `signals` its one view).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import ClassVar, Final

import numpy as np

from robofailring.calibration.bands import MIN_BAND_RUNS, fit_band, leave_one_out
from robofailring.detection.band import NONE, Band
from robofailring.detection.view_scores import ViewScores
from robofailring.errors import SettingError
from robofailring.memory.signals.modality import (
    CAMERAS_GROUP,
    FUSION_GROUPS,
    SIGNALS_GROUP,
    SIGNALS_VIEW,
    split_views,
)

# a fusion's calibration: each run's conformal score and the band of all runs (None: no band), from the runs'
# per-view scores, the band kind and each run's task
PeaksOf = Callable[[Sequence[Mapping[str, np.ndarray]], str, Sequence[str]], tuple[list[float], Band | None]]

MAX: Final[str] = "max"
PER_VIEW: Final[str] = "per-view"
PER_MODALITY: Final[str] = "per-modality"
DEFAULT_FUSION: Final[str] = PER_MODALITY  # the benchmarks' best (docs/signals.md, "Measured")


def fused_raw(scores: Mapping[str, np.ndarray]) -> np.ndarray:
    """max over views of one run's per-frame scores (NaN where no view was scored)."""
    length = max((len(values) for values in scores.values()), default=0)
    fused = ViewScores(dict(scores), length).fused_max()
    return np.where(np.isfinite(fused), fused, np.nan)


def peak(values: np.ndarray) -> float:
    """The highest finite value (a run's conformal score), NaN when none is finite."""
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else float("nan")


def per_view_peaks(
    runs: Sequence[Mapping[str, np.ndarray]], kind: str, tasks: Sequence[str] = ()
) -> tuple[list[float], Band | None]:
    """Each calibration run's conformal score under `per-view` fusion with a band of `kind`, and the band of
    all runs (one per view; `tasks` is not used). With `none`, or fewer than `MIN_BAND_RUNS` runs with a score,
    nothing is corrected: the peaks of the max over views and no band, as with `max`. A run with nothing scored
    gives NaN."""
    fused = [fused_raw(run) for run in runs]
    scored = [i for i, values in enumerate(fused) if np.isfinite(values).any()]
    if kind == NONE or len(scored) < MIN_BAND_RUNS:
        return [peak(values) for values in fused], None
    pooled_others = dict(zip(scored, leave_one_out(kind, [fused[i] for i in scored]), strict=True))
    corrected: list[dict[str, np.ndarray]] = [{} for _ in runs]
    own: dict[str, Band] = {}
    for view in dict.fromkeys(view for run in runs for view in run):
        rows = [i for i in scored if view in runs[i] and np.isfinite(runs[i][view]).any()]
        if len(rows) < MIN_BAND_RUNS:
            for i in rows:
                corrected[i][view] = pooled_others[i].correct(runs[i][view])
            continue
        views = [runs[i][view] for i in rows]
        for i, others in zip(rows, leave_one_out(kind, views), strict=True):
            corrected[i][view] = others.correct(runs[i][view])
        own[view] = fit_band(kind, views)
    peaks = [peak(fused_raw(values)) if values else float("nan") for values in corrected]
    return peaks, replace(fit_band(kind, [fused[i] for i in scored]), views=own)


def per_modality_peaks(
    runs: Sequence[Mapping[str, np.ndarray]], kind: str, tasks: Sequence[str] = ()
) -> tuple[list[float], Band | None]:
    """Each calibration run's conformal score under `per-modality` fusion with a band of `kind`, and the band
    of all runs: the cameras' (fitted on the max over camera views), with the signals' as its view `signals`,
    which has a band per task (`tasks`: each run's) where the task has `MIN_BAND_RUNS` scored runs. With
    `none`, or fewer than `MIN_BAND_RUNS` runs with a score, nothing is corrected, as with `max`."""
    fused = [fused_raw(run) for run in runs]
    scored = [i for i, values in enumerate(fused) if np.isfinite(values).any()]
    if kind == NONE or len(scored) < MIN_BAND_RUNS:
        return [peak(values) for values in fused], None
    pooled = fit_band(kind, [fused[i] for i in scored])
    pooled_others = dict(zip(scored, leave_one_out(kind, [fused[i] for i in scored]), strict=True))
    modalities = [_groups(run) for run in runs]
    corrected: list[dict[str, np.ndarray]] = [{} for _ in runs]
    own: dict[str, Band] = {}
    for name in FUSION_GROUPS:
        rows = [i for i in scored if name in modalities[i] and np.isfinite(modalities[i][name]).any()]
        if not rows:
            continue
        series = [modalities[i][name] for i in rows]
        if len(rows) < MIN_BAND_RUNS:
            others = [pooled_others[i] for i in rows]
            own[name] = pooled
        else:
            others = leave_one_out(kind, series)
            own[name] = fit_band(kind, series)
        if name == SIGNALS_GROUP and tasks:  # the signal memory is per task (its normalisation, its layout)
            others, own[name] = _by_task(kind, rows, series, [tasks[i] for i in rows], others, own[name])
        for i, values, band in zip(rows, series, others, strict=True):
            corrected[i][name] = band.correct(values)
    peaks = [peak(fused_raw(values)) if values else float("nan") for values in corrected]
    cameras = own.get(CAMERAS_GROUP, pooled)
    views = {SIGNALS_VIEW: own[SIGNALS_GROUP]} if SIGNALS_GROUP in own else {}
    return peaks, replace(cameras, views=views)


def _by_task(
    kind: str, rows: list[int], series: list[np.ndarray], tasks: list[str], others: list[Band], pooled: Band
) -> tuple[list[Band], Band]:
    """`others` (each run's band fitted without it) and `pooled` with a band per task that has `MIN_BAND_RUNS`
    runs among `series`: those runs' bands fitted on their task's other runs, the task's kept in `tasks`."""
    others = list(others)
    own: dict[str, Band] = {}
    for task in dict.fromkeys(tasks):
        mine = [k for k, of in enumerate(tasks) if of == task]
        if len(mine) < MIN_BAND_RUNS:
            continue
        for k, band in zip(mine, leave_one_out(kind, [series[k] for k in mine]), strict=True):
            others[k] = band
        own[task] = fit_band(kind, [series[k] for k in mine])
    return others, replace(pooled, tasks=own) if own else pooled


def _groups(run: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A run's scores per fusion group, where it has the group's views: the max over its camera views, and its
    signals view's."""
    cameras, signals = split_views(run)
    groups = {CAMERAS_GROUP: fused_raw({view: run[view] for view in cameras})} if cameras else {}
    return groups | ({SIGNALS_GROUP: run[signals[0]]} if signals else {})


def per_task_peaks(
    fusion_peaks: PeaksOf, runs: Sequence[Mapping[str, np.ndarray]], tasks: Sequence[str], kind: str
) -> tuple[list[float], Band | None]:
    """`fusion_peaks` with band scope `task`: the runs of a task that has `MIN_BAND_RUNS` scored calibration
    runs are corrected by bands fitted on that task's other runs alone and its band is kept in `Band.tasks`;
    the other runs are corrected as over all tasks (the pooled band, which judges their tasks)."""
    peaks, pooled = fusion_peaks(runs, kind, tasks)
    if pooled is None:
        return peaks, None
    peaks = list(peaks)
    own: dict[str, Band] = {}
    for task in dict.fromkeys(tasks):
        rows = [i for i, of in enumerate(tasks) if of == task]
        task_peaks, band = fusion_peaks([runs[i] for i in rows], kind, ())
        if band is None:  # too few of its runs: the pooled band
            continue
        for i, value in zip(rows, task_peaks, strict=True):
            peaks[i] = value
        own[task] = band
    return peaks, replace(pooled, tasks=own)


def conformal_peaks(runs: Sequence[np.ndarray], band: str) -> tuple[list[float], Band | None]:
    """Each run's conformal score (its peak; with a band, the peak of its score corrected by the band of
    the other runs) and the band of all of them (None for `none`, and with fewer than `MIN_BAND_RUNS`
    runs). A run with nothing scored (the only success run of its task: nothing to contrast it with)
    gives NaN."""
    finite = [run for run in runs if np.isfinite(run).any()]
    if band == NONE or len(finite) < MIN_BAND_RUNS:
        return [peak(run) for run in runs], None
    others = iter(leave_one_out(band, finite))
    peaks = [peak(next(others).correct(run)) if np.isfinite(run).any() else float("nan") for run in runs]
    return peaks, fit_band(band, finite)


def max_peaks(
    runs: Sequence[Mapping[str, np.ndarray]], kind: str, tasks: Sequence[str] = ()
) -> tuple[list[float], Band | None]:
    """`conformal_peaks` of the max over views of each run (`max` fusion; `tasks` is not used)."""
    return conformal_peaks([fused_raw(run) for run in runs], kind)


class Fusion(ABC):
    """One way the views meet a threshold: its name, its calibration peaks, and its bands as calibration's summary
    and stored method say them. A new fusion is one subclass added to `FUSIONS`."""

    name: ClassVar[str]  # `--fusion`'s choice, kept in a `ThresholdPolicy` and a calibration's result
    bands: ClassVar[str]  # the bands it fits, as calibration's summary and stored method say them
    help: ClassVar[str]  # what it does, in `--fusion`'s help

    @abstractmethod
    def peaks(
        self, runs: Sequence[Mapping[str, np.ndarray]], kind: str, tasks: Sequence[str] = ()
    ) -> tuple[list[float], Band | None]:
        """Each calibration run's conformal score from its per-view scores, corrected by bands of `kind` fitted
        on the other runs, and the band of all runs (None: no band); `tasks` is each run's task."""

    def method_note(self) -> str:
        """What the stored calibration method says of this fusion's bands (`, a band per view`)."""
        return f", {self.bands}"

    def summary_note(self) -> str:
        """What calibration's summary says of this fusion's bands after the band's line."""
        return f"; {self.bands} (fusion {self.name})"

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __str__(self) -> str:
        return self.name


class MaxFusion(Fusion):
    """`max` (the paper's eq. 7): one band, fitted on the max over views, corrects every view."""

    name = MAX
    bands = "one band"
    help = "max, the paper's, fires when any view reaches it, every view corrected by one band (of the max over views)"

    def peaks(
        self, runs: Sequence[Mapping[str, np.ndarray]], kind: str, tasks: Sequence[str] = ()
    ) -> tuple[list[float], Band | None]:
        return max_peaks(runs, kind, tasks)

    def method_note(self) -> str:  # one band is what every calibration has: nothing to add
        return ""

    def summary_note(self) -> str:
        return ""


class PerViewFusion(Fusion):
    """`per-view`: each view corrected by a band of its own calibration scores before the max."""

    name = PER_VIEW
    bands = "a band per view"
    help = "per-view corrects each view by a band of its own calibration scores first"

    def peaks(
        self, runs: Sequence[Mapping[str, np.ndarray]], kind: str, tasks: Sequence[str] = ()
    ) -> tuple[list[float], Band | None]:
        return per_view_peaks(runs, kind, tasks)


class PerModalityFusion(Fusion):
    """`per-modality`: the camera views one band of their max, the robot's signals their own (per task)."""

    name = PER_MODALITY
    bands = "a band per modality (the cameras', and the signals' per task)"
    help = (
        "per-modality, one band for the cameras and one for the robot's signals (per task where a task has enough "
        "runs)"
    )

    def peaks(
        self, runs: Sequence[Mapping[str, np.ndarray]], kind: str, tasks: Sequence[str] = ()
    ) -> tuple[list[float], Band | None]:
        return per_modality_peaks(runs, kind, tasks)


FUSIONS: Final[dict[str, Fusion]] = {
    fusion.name: fusion for fusion in (MaxFusion(), PerViewFusion(), PerModalityFusion())
}


def check_fusion(fusion: str) -> str:
    """A view fusion (`max`, `per-view`, `per-modality`); SettingError naming the choices otherwise."""
    fusion_named(fusion)
    return fusion


def fusion_named(name: str) -> Fusion:
    """The fusion called `name`; SettingError naming the choices otherwise."""
    try:
        return FUSIONS[name]
    except KeyError:
        raise SettingError(f"unknown view fusion {name!r}; choose one of {list(FUSIONS)}") from None
