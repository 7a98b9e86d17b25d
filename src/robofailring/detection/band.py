"""The time-indexed band a rule's threshold applies to, as the detector applies it (docs/rules.md,
"Time-indexed thresholds"): a statistic per frame index of the calibration successes' scores.

`shift` subtracts their mean μ_t from a run's score at frame t, `norm` also divides by their spread σ_t; on the
raw score the threshold is the line μ_t + θ·σ_t, which recordings draw. A band may have a band per view (fusion
`per-view`, `per-modality`) and per task (scope `task`); a run is judged by its task's bands (`Band.for_task`).
Calibration fits bands (`robofailring.calibration.bands`); the detector reads them from a memory's manifest.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Final

import numpy as np

from robofailring.errors import MemoryFormatError

NONE: Final[str] = "none"
SHIFT: Final[str] = "shift"
NORM: Final[str] = "norm"


@dataclass(frozen=True)
class Band:
    """One rule's per-frame-index statistic: corrected = (score − mean_t) / scale_t."""

    kind: str  # `shift` or `norm`
    mean: np.ndarray  # (T,) μ_t
    scale: np.ndarray  # (T,) σ_t (ones for `shift`)
    runs: int  # calibration runs it was fitted on
    # per view, its own band (fusion `per-view`, robofailring.calibration.fusions); a view not named here
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
