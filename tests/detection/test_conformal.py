"""The split-conformal threshold and the peak-score AUC against hand-worked cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robofailring.detection.conformal import auc, conformal_threshold, empirical_fpr, successes_needed
from robofailring.errors import DataError, SettingError


@pytest.mark.parametrize(
    ("n", "alpha", "rank"), [(19, 0.05, 19), (39, 0.05, 38), (9, 0.2, 8), (100, 0.05, 96)]
)
def test_conformal_threshold_sits_just_above_the_ranked_peak(n: int, alpha: float, rank: int) -> None:
    rng = np.random.default_rng(n)
    peaks = rng.permutation(np.linspace(-0.3, 0.4, n)).astype(np.float32)
    assert rank == math.ceil((n + 1) * (1 - alpha) - 1e-9)
    threshold = conformal_threshold(peaks.tolist(), alpha)
    ranked = np.sort(peaks)[rank - 1]
    assert threshold > ranked and np.nextafter(np.float32(threshold), np.float32(-1)) == ranked
    # exactly the runs ranked above k fire: n − k of n
    assert empirical_fpr(peaks.tolist(), threshold) == pytest.approx((n - rank) / n)


def test_too_few_successes_says_how_many_and_the_smallest_alpha() -> None:
    assert successes_needed(0.05) == 19 and successes_needed(0.2) == 4
    with pytest.raises(
        DataError, match=r"needs at least 19 success runs.*got 10.*smallest α these 10 runs allow is 0\.0909"
    ):
        conformal_threshold([0.1] * 10, 0.05)
    conformal_threshold([0.1] * 19, 0.05)  # exactly enough
    with pytest.raises(DataError, match="got 0"):
        conformal_threshold([], 0.5)
    with pytest.raises(SettingError, match="target FPR"):
        conformal_threshold([0.1] * 50, 0.0)


def test_auc_counts_pairs_and_ties() -> None:
    assert auc([0.9, 0.8], [0.1, 0.2]) == 1.0
    assert auc([0.1], [0.9]) == 0.0
    assert auc([0.5, 0.9], [0.5, 0.1]) == pytest.approx((0.5 + 1 + 1 + 1) / 4)
    assert math.isnan(auc([], [0.1]))
