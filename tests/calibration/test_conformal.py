"""The split-conformal threshold and the peak-score AUC against hand-worked cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from environment import require_module

from robofailring.calibration.conformal import (
    attainable_target_fpr,
    auc,
    auc_interval,
    beta_cdf,
    beta_quantile,
    binomial_tail,
    conformal_threshold,
    empirical_fpr,
    fpr_spread,
    realised_fpr_parameters,
    runs_for_bound,
    successes_needed,
)
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


def test_too_few_successes_fall_back_to_the_smallest_alpha_they_allow() -> None:
    assert attainable_target_fpr(19, 0.05) == 0.05  # enough: α itself
    assert attainable_target_fpr(5, 0.05) == pytest.approx(1 / 6)
    assert attainable_target_fpr(1, 0.05) == pytest.approx(1 / 2)
    peaks = [0.3, 0.1, 0.7, 0.2, 0.5]
    threshold = conformal_threshold(peaks, attainable_target_fpr(len(peaks), 0.05))
    assert threshold > 0.7 and np.nextafter(np.float32(threshold), np.float32(-1)) == np.float32(0.7)
    with pytest.raises(DataError, match="no calibration run"):
        attainable_target_fpr(0, 0.05)


@pytest.mark.parametrize("alpha", [0.05, 0.1, 0.2, 0.25, 0.5])
def test_every_count_of_runs_from_the_needed_one_on_keeps_alpha_itself(alpha: float) -> None:
    """From ⌈1/α − 1⌉ runs on the level is α, at every count (20 runs at α = 0.05 too, not 1/21); below it,
    the smallest level the runs allow, 1/(n+1), at which a threshold exists."""
    needed = successes_needed(alpha)
    assert [n for n in range(needed, 400) if attainable_target_fpr(n, alpha) != alpha] == []
    assert attainable_target_fpr(20, 0.05) == 0.05
    for n in range(1, needed):
        level = attainable_target_fpr(n, alpha)
        assert level == pytest.approx(1 / (n + 1)) and level > alpha
        conformal_threshold([0.1 * i for i in range(n)], level)  # a threshold exists at that level


def test_auc_interval_resamples_each_kind_of_run() -> None:
    assert auc_interval([0.9, 0.8, 0.7], [0.1, 0.2]) == (1.0, 1.0)  # every resample separates them
    assert auc_interval([], [0.1]) is None and auc_interval([0.1], []) is None
    # one run of a kind: every resample draws it, and [0.00, 0.00] would claim a certainty it cannot give
    assert auc_interval([0.1, 0.2, 0.3], [0.9]) is None and auc_interval([0.9], [0.1, 0.2]) is None
    assert auc_interval([0.1, 0.2], [0.9, 0.8]) == (0.0, 0.0)  # two of each: an interval
    rng = np.random.default_rng(3)
    failures, successes = rng.normal(1.0, 1.0, 30), rng.normal(0.0, 1.0, 40)
    low, high = auc_interval(failures.tolist(), successes.tolist()) or (0.0, 0.0)
    assert low < auc(failures.tolist(), successes.tolist()) < high
    assert auc_interval(failures.tolist(), successes.tolist()) == (low, high)  # a fixed seed
    # the same interval as resampling the runs one draw at a time (up to the draws' own noise)
    draws = [
        auc(rng.choice(failures, failures.size).tolist(), rng.choice(successes, successes.size).tolist())
        for _ in range(2000)
    ]
    assert np.percentile(draws, [2.5, 97.5]) == pytest.approx([low, high], abs=0.02)


def test_auc_counts_pairs_and_ties() -> None:
    assert auc([0.9, 0.8], [0.1, 0.2]) == 1.0
    assert auc([0.1], [0.9]) == 0.0
    assert auc([0.5, 0.9], [0.5, 0.1]) == pytest.approx((0.5 + 1 + 1 + 1) / 4)
    assert math.isnan(auc([], [0.1]))


@pytest.mark.parametrize(("n", "alpha"), [(19, 0.05), (39, 0.05), (60, 0.1), (24, 0.2)])
def test_fpr_spread_matches_simulated_calibration_sets(n: int, alpha: float) -> None:
    """Many calibration sets of uniform success scores: the realised FPR of each set's threshold (the
    chance a new uniform score reaches it, 1 − threshold) has the quantiles `fpr_spread` reports."""
    rng = np.random.default_rng(n)
    realised = np.array(
        [1.0 - conformal_threshold(rng.random(n).tolist(), alpha) for _ in range(6000)], dtype=np.float64
    )
    spread = fpr_spread(n, alpha)
    assert np.quantile(realised, 0.05) == pytest.approx(spread.low, abs=0.006)
    assert np.quantile(realised, 0.95) == pytest.approx(spread.high, abs=0.012)
    assert realised.mean() == pytest.approx(spread.mean, abs=0.003)
    assert spread.mean <= alpha + 1e-12  # the promise holds on average ...
    assert spread.high > alpha  # ... and one calibration set can miss it


def test_fpr_spread_known_values() -> None:
    # n = 19 at α = 0.05: k = 19, Beta(1, 19), whose quantile q is 1 − (1 − q)^(1/19)
    spread = fpr_spread(19, 0.05)
    assert spread.low == pytest.approx(1 - 0.95 ** (1 / 19), abs=1e-9)
    assert spread.high == pytest.approx(1 - 0.05 ** (1 / 19), abs=1e-9)
    assert spread.mean == pytest.approx(1 / 20) and spread.bound == pytest.approx(0.07)
    assert realised_fpr_parameters(39, 0.05) == (2, 38) and realised_fpr_parameters(100, 0.05) == (5, 96)
    # Beta(5, 96): values of scipy.stats.beta.ppf
    assert beta_quantile(0.05, 5, 96) == pytest.approx(0.0199055637, abs=1e-8)
    assert beta_quantile(0.95, 5, 96) == pytest.approx(0.0891962502, abs=1e-8)
    assert beta_cdf(0.3, 1, 1) == pytest.approx(0.3) and beta_cdf(0.5, 3, 3) == pytest.approx(0.5)
    assert binomial_tail(4, 0.5, 2) == pytest.approx(11 / 16)
    assert "0.3–14.6 %" in spread.to_text() and "360 runs" in spread.to_text()
    with pytest.raises(DataError, match="at least 19 needed"):
        fpr_spread(10, 0.05)


@pytest.mark.parametrize("alpha", [0.01, 0.05, 0.1, 0.2])
def test_runs_for_bound_is_the_first_n_from_which_the_quantile_stays_within(alpha: float) -> None:
    bound = alpha + 0.02
    runs = runs_for_bound(alpha, bound)
    assert runs is not None

    def within(n: int) -> bool:  # the 95 % quantile ≤ bound ⟺ P(realised FPR ≤ bound) ≥ 0.95
        return beta_cdf(bound, *realised_fpr_parameters(n, alpha)) >= 0.95

    assert all(within(n) for n in range(runs, 2 * runs))  # every n from there on keeps it within
    if runs > successes_needed(alpha):
        assert not within(runs - 1)  # and one fewer does not
    assert fpr_spread(runs, alpha).high <= bound
    with pytest.raises(SettingError, match="bound"):
        runs_for_bound(alpha, alpha)


def test_beta_quantiles_agree_with_scipy() -> None:
    stats = require_module("scipy.stats", "pip install scipy (umap-learn, of the viz extra, brings it)")
    for n, alpha in [(19, 0.05), (250, 0.05), (77, 0.1), (1000, 0.01)]:
        a, b = realised_fpr_parameters(n, alpha)
        for q in (0.05, 0.5, 0.95):
            assert beta_quantile(q, a, b) == pytest.approx(float(stats.beta.ppf(q, a, b)), abs=1e-8)
