"""Paper §4.1.3 metrics from per-trajectory score traces: Recall, FPR, T_s, detection progress."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np

from robofailring.data.model import Trajectory
from robofailring.detection.view_scores import ViewScores


def mean_or_nan(values: Sequence[float]) -> float:
    """The mean of `values`, NaN when there are none (a table shows it as —)."""
    return float(np.mean(values)) if len(values) else float("nan")


def median_or_nan(values: Sequence[float]) -> float:
    """The median of `values`, NaN when there are none."""
    return float(np.median(values)) if len(values) else float("nan")


PAPER_DELTAS: Final[tuple[float, ...]] = (0.85, 0.90, 0.92, 0.95)


@dataclass(frozen=True)
class ScoredTrajectory:
    """What evaluation keeps of one test trajectory: its label and S_t per view (L values each)."""

    key: str
    task: str
    symbol: str | None
    is_failure: bool
    length: int
    similarity: dict[str, np.ndarray]  # the score per view: S_t, or the contrast rule's C_t (rule_evaluation)
    onset_frame: int | None = None  # where the failure starts (Trajectory.onset_frame), None: unknown
    fps: float | None = None  # the data's frame rate, for delays in seconds

    @classmethod
    def of(cls, trajectory: Trajectory, length: int, similarity: dict[str, np.ndarray]) -> ScoredTrajectory:
        """`trajectory`'s label (task, failure symbol, onset, frame rate) with its scores over `length` frames."""
        return cls(
            key=trajectory.key,
            task=trajectory.task,
            symbol=trajectory.symbol,
            is_failure=trajectory.is_failure,
            length=length,
            similarity=similarity,
            onset_frame=trajectory.onset_frame,
            fps=trajectory.frame_rate,
        )

    @property
    def view_scores(self) -> ViewScores:
        return ViewScores(self.similarity, self.length)

    def scores(self, views: Sequence[str] | None = None) -> np.ndarray:
        """max over the chosen views of S_t, per frame (NaN counts as never firing)."""
        return self.view_scores.fused_max(views)

    def peak(self, views: Sequence[str] | None = None) -> np.floating:
        """The highest fused score (−∞ when nothing was scored), in the scores' own precision: the
        trajectory fires at δ (has a t_det) exactly when peak ≥ δ."""
        return self.scores(views).max(initial=-np.inf)

    def t_det(self, delta: float, views: Sequence[str] | None = None) -> int | None:
        """First frame whose fused score reaches δ, or None."""
        return self.view_scores.first_at_or_above(delta, views)


class ConfusionRates:
    """Recall and FPR of the confusion counts a result holds: one definition for every table."""

    tp: int
    fn: int
    fp: int
    tn: int

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else float("nan")

    @property
    def fpr(self) -> float:
        return self.fp / (self.fp + self.tn) if self.fp + self.tn else float("nan")


@dataclass(frozen=True)
class Rates(ConfusionRates):
    """Confusion counts and rates at one δ."""

    delta: float
    tp: int
    fn: int
    fp: int
    tn: int


def rates(
    trajectories: Sequence[ScoredTrajectory], delta: float, views: Sequence[str] | None = None
) -> Rates:
    """Recall = TP/(TP+FN) over failures, FPR = FP/(FP+TN) over successes."""
    return sweep(trajectories, [delta], views)[0]


def sweep(
    trajectories: Sequence[ScoredTrajectory], deltas: Sequence[float], views: Sequence[str] | None = None
) -> list[Rates]:
    """Rates over a sequence of thresholds (the Recall/FPR curve).

    A trajectory fires at δ when its fused peak reaches δ (its t_det exists), so each trajectory's
    peak is found once and every δ is a comparison of the peaks.
    """
    peaks = [trajectory.peak(views) for trajectory in trajectories]
    failure = np.array([trajectory.is_failure for trajectory in trajectories], dtype=bool)
    failures, successes = int(failure.sum()), int((~failure).sum())
    curve = []
    for delta in deltas:
        fired = np.fromiter((peak >= float(delta) for peak in peaks), dtype=bool, count=len(peaks))
        tp, fp = int(np.sum(fired & failure)), int(np.sum(fired & ~failure))
        curve.append(Rates(delta=float(delta), tp=tp, fn=failures - tp, fp=fp, tn=successes - fp))
    return curve


def fine_grid(trajectories: Sequence[ScoredTrajectory], *, steps: int = 101) -> list[float]:
    """A δ grid spanning the observed peak scores (plus the paper's δs), for the sweep curve."""
    peaks = [float(t.peak()) for t in trajectories if t.length]
    finite = [p for p in peaks if np.isfinite(p)]
    low = min([*finite, min(PAPER_DELTAS)]) - 0.01
    high = min(max([*finite, max(PAPER_DELTAS)]) + 0.01, 1.0 + 1e-6)
    grid = {round(float(d), 4) for d in np.linspace(low, high, steps)} | set(PAPER_DELTAS)
    return sorted(grid)


@dataclass(frozen=True)
class Timeliness:
    """Detection progress t_det/L and temporal saving ratio T_s = 1 − t_det/L over detected failures."""

    progress: tuple[float, ...]

    @property
    def count(self) -> int:
        return len(self.progress)

    @property
    def mean_progress(self) -> float:
        return mean_or_nan(self.progress)

    @property
    def median_progress(self) -> float:
        return median_or_nan(self.progress)

    @property
    def mean_saving(self) -> float:
        return 1.0 - self.mean_progress

    @property
    def median_saving(self) -> float:
        return 1.0 - self.median_progress

    def histogram(self, bins: int = 10) -> tuple[list[int], list[float]]:
        counts, edges = np.histogram(np.asarray(self.progress, dtype=float), bins=bins, range=(0.0, 1.0))
        return [int(c) for c in counts], [float(e) for e in edges]


def timeliness(
    trajectories: Sequence[ScoredTrajectory], delta: float, views: Sequence[str] | None = None
) -> Timeliness:
    progress = []
    for trajectory in trajectories:
        if not trajectory.is_failure or trajectory.length == 0:
            continue
        t_det = trajectory.t_det(delta, views)
        if t_det is not None:
            progress.append(t_det / trajectory.length)
    return Timeliness(progress=tuple(progress))


def json_number(value: float) -> float | None:
    """A metric for JSON: NaN (undefined, e.g. recall without failures) becomes null."""
    return None if math.isnan(value) else round(float(value), 6)
