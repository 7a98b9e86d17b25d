"""One trajectory's per-view scores and how they are fused over views (paper eq. 7), written once.

Firing, t_det and the detected view are judged here and nowhere else: the detector's live step,
its trace (`robofailring.detection.trace.DetectionTrace`) and the evaluation's scored trajectories
(`robofailring.evaluation.metrics.ScoredTrajectory`) all judge through `ViewScores`: the fused score is the max
over views, a NaN (a frame not scored, or no success memory) counts as −∞ and so never fires, and
t_det is the first frame whose fused score reaches the threshold. `reaches` is that comparison, the one
way an alarm is decided (calibration's empirical FPR counts with it too). A live step may judge each view
against its own threshold (a band per view, `robofailring.calibration.fusions`): `firing` and
`strongest` take one threshold or one per view.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TypeAlias

import numpy as np
from numpy.typing import ArrayLike

Thresholds: TypeAlias = float | Mapping[str, float]  # one for every view, or one per view


def reaches(score: ArrayLike, threshold: ArrayLike) -> np.ndarray:
    """Where `score` reaches `threshold` (≥; NaN never does): what fires an alarm, everywhere."""
    return np.asarray(np.asarray(score) >= threshold)


def _of(threshold: Thresholds, view: str) -> float:
    return threshold if isinstance(threshold, (int, float)) else threshold[view]


@dataclass(frozen=True)
class ViewScores:
    """A score per view per frame (S⁻_t or C_t), L values each."""

    by_view: Mapping[str, np.ndarray]
    length: int  # L: frames per view

    def chosen(self, views: Sequence[str] | None = None) -> list[str]:
        """The given views that have scores (all of them, in their order, when none are given)."""
        return [v for v in (views or list(self.by_view)) if v in self.by_view]

    def fused_max(self, views: Sequence[str] | None = None) -> np.ndarray:
        """max over the chosen views of the score, per frame; NaN counts as −∞ (−∞ throughout without views)."""
        chosen = self.chosen(views)
        if not chosen:
            return np.full(self.length, -np.inf)
        return np.stack([np.nan_to_num(self.by_view[v], nan=-np.inf) for v in chosen]).max(axis=0)

    def state(self, threshold: float, views: Sequence[str] | None = None) -> np.ndarray:
        """State_t (eq. 7): True where any chosen view's score reaches `threshold`."""
        return reaches(self.fused_max(views), threshold)

    def first_at_or_above(self, threshold: float, views: Sequence[str] | None = None) -> int | None:
        """t_det: the first frame whose fused score reaches `threshold`, or None."""
        fired = np.flatnonzero(self.state(threshold, views))
        return int(fired[0]) if fired.size else None

    def firing(self, threshold: Thresholds, t: int, views: Sequence[str] | None = None) -> list[str]:
        """The chosen views whose score at frame `t` reaches `threshold` (its own, given per view), in view
        order (NaN never fires)."""
        return [v for v in self.chosen(views) if reaches(self.by_view[v][t], _of(threshold, v))]

    def strongest(self, threshold: Thresholds, t: int, views: Sequence[str] | None = None) -> str | None:
        """The firing view whose score at frame `t` is highest over its threshold (with one threshold: the
        highest score; the first of equals, in view order), or None."""
        fired = self.firing(threshold, t, views)
        return max(fired, key=lambda v: float(self.by_view[v][t]) - _of(threshold, v)) if fired else None

    def detected_view(self, threshold: float, views: Sequence[str] | None = None) -> str | None:
        """The view with the highest score at t_det (the first of equals, in view order), or None."""
        t = self.first_at_or_above(threshold, views)
        return None if t is None else self.strongest(threshold, t, views)
