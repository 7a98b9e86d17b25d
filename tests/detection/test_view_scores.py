"""Fusing per-view scores over views (paper eq. 7): max over views, NaN never fires, t_det and its view."""

from __future__ import annotations

import numpy as np

from robofailring.calibration.conformal import empirical_fpr
from robofailring.detection.view_scores import ViewScores, reaches
from robofailring.evaluation.metrics import ScoredTrajectory

NAN = float("nan")


def _scores() -> ViewScores:
    return ViewScores(
        {
            "front": np.array([0.1, NAN, 0.7, 0.95], np.float32),
            "wrist": np.array([NAN, 0.5, 0.9, 0.2], np.float32),
        },
        4,
    )


def test_fused_max_treats_nan_as_never_firing() -> None:
    fused = _scores().fused_max()
    np.testing.assert_allclose(fused, [0.1, 0.5, 0.9, 0.95], rtol=1e-6)
    assert _scores().first_at_or_above(0.5) == 1 and _scores().first_at_or_above(0.92) == 3
    assert _scores().first_at_or_above(0.99) is None
    np.testing.assert_array_equal(_scores().state(0.8), [False, False, True, True])
    all_nan = ViewScores({"front": np.full(3, NAN)}, 3)
    assert all_nan.first_at_or_above(-1e9) is None and all_nan.detected_view(-1e9) is None


def test_detected_view_is_the_highest_at_t_det_and_views_can_be_chosen() -> None:
    assert _scores().detected_view(0.8) == "wrist"  # t_det = 2: wrist 0.9 over front 0.7
    assert _scores().detected_view(0.92) == "front"
    assert _scores().first_at_or_above(0.8, ["front"]) == 3
    assert _scores().detected_view(0.8, ["front", "missing"]) == "front"
    assert (
        np.isneginf(ViewScores({}, 2).fused_max()).all() and ViewScores({}, 2).first_at_or_above(0.0) is None
    )


def test_a_step_fires_where_views_reach_the_threshold_and_its_view_is_the_strongest() -> None:
    scores = _scores()
    assert scores.firing(0.6, 2) == ["front", "wrist"]  # in view order
    assert scores.strongest(0.6, 2) == "wrist"  # 0.9 over 0.7: the highest, not the first firing
    assert scores.firing(0.4, 1) == ["wrist"] and scores.strongest(0.4, 1) == "wrist"  # NaN never fires
    assert scores.firing(0.99, 3) == [] and scores.strongest(0.99, 3) is None
    assert scores.strongest(0.6, 2, ["front"]) == "front"


def test_the_evaluation_judges_through_the_same_type() -> None:
    scores = _scores()
    scored = ScoredTrajectory(
        key="e", task="t", symbol=None, is_failure=False, length=4, similarity=dict(scores.by_view)
    )
    np.testing.assert_array_equal(scored.scores(), scores.fused_max())
    assert scored.t_det(0.8) == 2 and scored.t_det(0.8, ["front"]) == 3


def test_a_score_equal_to_the_threshold_fires_everywhere_alarms_are_decided() -> None:
    """`reaches` (≥) is the one comparison: the fused state, a step's firing views, t_det and the calibration's
    empirical FPR all count a score exactly at the threshold as an alarm."""
    np.testing.assert_array_equal(
        reaches(np.float32([0.5, 0.4999, NAN, 0.7]), 0.5), [True, False, False, True]
    )
    scores = ViewScores({"front": np.float32([0.25, 0.5, NAN]), "wrist": np.float32([NAN, 0.1, 0.5])}, 3)
    np.testing.assert_array_equal(scores.state(0.5), [False, True, True])
    assert scores.firing(0.5, 1) == ["front"] and scores.firing({"front": 0.6, "wrist": 0.5}, 2) == ["wrist"]
    assert scores.first_at_or_above(0.5) == 1 and scores.detected_view(0.5) == "front"
    assert empirical_fpr([0.5, 0.25, 0.5, 0.75], 0.5) == 0.75
