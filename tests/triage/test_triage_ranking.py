"""The triage ranking: each task's scale, the order, and the quality measures the bench reports."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robofailring.triage.ranking import MIN_SPREAD, TaskScale, rank, ranking_quality
from robofailring.triage.scoring import EpisodeScore


def _score(task: str, episode: str, peak: float, threshold: float = 0.1) -> EpisodeScore:
    return EpisodeScore(
        task=task,
        episode=episode,
        mode="others",
        rule="novelty",
        threshold=threshold,
        curve=np.asarray([peak], np.float32),
        peak=peak,
        frame=0 if math.isfinite(peak) else -1,
    )


def test_task_scale_is_median_and_mad_with_a_floor() -> None:
    scale = TaskScale.of([0.1, 0.2, 0.3, float("nan")])
    assert scale is not None
    assert scale.center == pytest.approx(0.2)
    assert scale.spread == pytest.approx(1.4826 * 0.1)
    assert TaskScale.of([0.5, 0.5]) == TaskScale(center=0.5, spread=MIN_SPREAD)
    assert TaskScale.of([float("nan")]) is None


def test_tasks_are_ranked_on_their_own_scale_and_unscored_last() -> None:
    # task b's runs vary ten times more: its peak of 0.5 is less unusual than task a's 0.15
    scores = [
        _score("a", "a1", 0.15),
        _score("a", "a2", 0.10),
        _score("b", "b1", 0.5),
        _score("b", "b2", 0.1),
        _score("b", "b3", float("nan")),
        _score("c", "c1", 0.3, threshold=0.2),
    ]
    scales = {"a": TaskScale(0.1, 0.01), "b": TaskScale(0.1, 0.1)}
    ranked = rank(scores, scales)
    assert [s.episode for s in ranked] == ["a1", "b1", "c1", "a2", "b2", "b3"]
    assert [s.rank for s in ranked] == [1, 2, 3, 4, 5, 6]
    assert ranked[0].rank_score == pytest.approx(5.0)
    assert ranked[2].rank_score == pytest.approx(0.1)  # no scale: the margin over the threshold
    assert math.isnan(ranked[-1].rank_score)


def test_ranking_quality_values() -> None:
    quality = ranking_quality([True, False, True, False, False, False, False, False, False, False])
    assert quality.failures == 2 and quality.episodes == 10
    assert quality.auc == pytest.approx((8 + 7) / 16)
    assert quality.precision_at(3) == pytest.approx(2 / 3)
    assert quality.recall_at(1) == pytest.approx(0.5)
    assert quality.top_share == pytest.approx(0.5)  # top 15 % of 10: the first 2 (rounded)
    perfect = ranking_quality([True] + [False] * 9)
    assert perfect.auc == 1.0 and perfect.top_share == 1.0


@given(st.lists(st.booleans(), min_size=1, max_size=60))
def test_ranking_quality_is_consistent(flags: list[bool]) -> None:
    quality = ranking_quality(flags)
    assert quality.hits[-1] == sum(flags)
    if 0 < sum(flags) < len(flags):
        assert 0.0 <= quality.auc <= 1.0
        assert quality.recall_at(len(flags)) == 1.0
        assert ranking_quality(sorted(flags, reverse=True)).auc == 1.0
