"""The triage ranking: each episode's peak score on its task's scale, and how good a ranking is.

Tasks differ in how much their normal runs vary, so a peak is put on its task's scale before the
tasks are ranked together: how many spreads it lies above the median peak of the task's episodes
(those not labelled failure, and its known-good runs, each scored leaving itself out),
(peak − median) / (1.4826 · MAD), the spread never below `MIN_SPREAD`. Median and MAD hold while
fewer than half the runs fail; they only place tasks beside each other, the order within a task is
that of its peaks. A task with no peak to scale by ranks by its peak's margin over the threshold.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Final

import numpy as np

from robofailring.triage.scoring import EpisodeScore

MIN_SPREAD: Final[float] = 1e-3  # a task whose reference runs all peak alike still ranks by distance
TOP_SHARE: Final[float] = 0.15  # "the top 15 % of the ranking" (docs/triage.md)


@dataclass(frozen=True)
class TaskScale:
    """Where a task's normal peaks lie (`center`) and how widely they vary (`spread`)."""

    center: float
    spread: float = 1.0

    @classmethod
    def of(cls, peaks: Sequence[float]) -> TaskScale | None:
        """The robust scale of reference peaks (median, 1.4826 · MAD); None when none is finite."""
        finite = np.asarray([p for p in peaks if np.isfinite(p)], dtype=np.float64)
        if not finite.size:
            return None
        center = float(np.median(finite))
        spread = 1.4826 * float(np.median(np.abs(finite - center)))
        return cls(center=center, spread=max(spread, MIN_SPREAD))

    def place(self, peak: float) -> float:
        return (peak - self.center) / self.spread


def rank(scores: Sequence[EpisodeScore], scales: Mapping[str, TaskScale | None]) -> list[EpisodeScore]:
    """The scores ranked, highest `rank_score` first (rank 1); episodes not scored come last.

    `scales` per task; a task without one (a memory's: its threshold is the centre) uses
    `TaskScale(threshold)`, the peak's margin over the rule's threshold."""
    placed = [
        replace(score, rank_score=(scales.get(score.task) or TaskScale(score.threshold)).place(score.peak))
        for score in scores
    ]
    ordered = sorted(
        placed,
        key=lambda s: (not np.isfinite(s.rank_score), -np.nan_to_num(s.rank_score, nan=0.0), s.key),
    )
    return [replace(score, rank=position) for position, score in enumerate(ordered, 1)]


@dataclass(frozen=True)
class RankingQuality:
    """How well a ranking puts the failures first (the bench and tests measure it against known outcomes)."""

    failures: int
    episodes: int
    auc: float  # the chance a failure ranks above a success
    top_share: float  # share of the failures in the top `TOP_SHARE` of the ranking
    hits: tuple[int, ...]  # per rank position: failures among the first that many episodes

    def precision_at(self, k: int) -> float:
        return self.hits[min(k, self.episodes) - 1] / min(k, self.episodes) if self.episodes else float("nan")

    def recall_at(self, k: int) -> float:
        return self.hits[min(k, self.episodes) - 1] / self.failures if self.failures else float("nan")


def ranking_quality(failed: Sequence[bool], *, top: float = TOP_SHARE) -> RankingQuality:
    """The quality of a ranking given, in rank order, whether each episode failed."""
    flags = np.asarray(failed, dtype=bool)
    count, failures = len(flags), int(flags.sum())
    hits = tuple(int(h) for h in np.cumsum(flags))
    successes = count - failures
    if failures and successes:
        positions = np.arange(count)
        # a failure at position p ranks above every success after it
        above = sum(int((~flags[p + 1 :]).sum()) for p in positions[flags])
        auc = above / (failures * successes)
    else:
        auc = float("nan")
    cut = max(1, round(top * count)) if count else 0
    share = hits[cut - 1] / failures if failures and cut else float("nan")
    return RankingQuality(failures=failures, episodes=count, auc=auc, top_share=share, hits=hits)
