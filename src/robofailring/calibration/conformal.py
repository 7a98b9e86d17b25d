"""Split-conformal calibration of a rule's threshold, how far its test FPR strays, and the peak-score AUC
with its bootstrap interval.

With n success runs' peak scores, the threshold sits just above the k = ⌈(n+1)(1−α)⌉-th smallest, so a
new exchangeable success run fires with probability ≤ α — on average over calibration sets. The FPR
one calibration set gives (its realised FPR) is Beta(n+1−k, k) (Vovk; Angelopoulos & Bates, "A gentle
introduction to conformal prediction", §3.2): `fpr_spread` reports its 5 %–95 % range and how many
runs would keep its 95 % quantile within α + `SPREAD_MARGIN`. The Beta quantiles need no scipy: for
integer parameters P(Beta(a, b) ≤ x) = P(Binomial(a+b−1, x) ≥ a).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

from robofailring.detection.view_scores import reaches
from robofailring.errors import DataError, SettingError


def check_target_fpr(target_fpr: float) -> float:
    """A target false-positive rate α for (conformal) calibration: within (0, 1) (SettingError otherwise)."""
    if not 0.0 < target_fpr < 1.0:
        raise SettingError(f"target FPR must be in (0, 1), got {target_fpr}")
    return target_fpr


def successes_needed(alpha: float) -> int:
    """The fewest success runs for which a conformal threshold at level α exists: ⌈1/α − 1⌉."""
    return max(math.ceil(1.0 / alpha - 1.0 - 1e-9), 1)


def runs_text(count: int) -> str:
    """A count of runs for a message: `12,345`, or `1e+300` past a billion (a tiny α needs a huge count)."""
    return f"{count:,}" if count < 10**9 else f"{float(count):.3g}"


def smallest_target_fpr(successes: int) -> float:
    """The smallest α that `successes` calibration runs allow: 1/(n+1) (n ≥ 1/α − 1)."""
    return 1.0 / (successes + 1)


def attainable_target_fpr(successes: int, alpha: float) -> float:
    """α when `successes` runs allow a threshold at it, else the smallest α they allow (1/(n+1), n ≥ 1):
    the level an evaluation on too few runs falls back to, where no guarantee at α holds."""
    check_target_fpr(alpha)
    if successes < 1:
        raise DataError(
            f"no calibration run: no threshold at any α (α = {alpha:g} needs {runs_text(successes_needed(alpha))})"
        )
    return alpha if conformal_rank(successes, alpha) <= successes else smallest_target_fpr(successes)


def conformal_rank(successes: int, alpha: float) -> int:
    """k = ⌈(n+1)(1−α)⌉: the rank of the calibration score the threshold sits just above (> n: none)."""
    return math.ceil((successes + 1) * (1.0 - alpha) - 1e-9)


def conformal_threshold(peaks: Sequence[float], alpha: float) -> float:
    """The split-conformal threshold for success peak scores at level α.

    The alarm fires when a score reaches the threshold; it is set just above the
    ⌈(n+1)(1−α)⌉-th smallest peak, so an exchangeable new success run fires with probability
    at most α. With n < 1/α − 1 runs no such threshold exists: DataError says how many are needed
    and the smallest α these runs allow (1/(n+1)).
    """
    check_target_fpr(alpha)
    values = np.sort(np.asarray([p for p in peaks if math.isfinite(p)], dtype=np.float32))
    n = int(values.size)
    rank = conformal_rank(n, alpha)
    if n == 0 or rank > n:
        smallest = f"; the smallest α these {n} runs allow is {smallest_target_fpr(n):.4g}" if n else ""
        raise DataError(
            f"a guaranteed false-positive rate of {alpha:g} needs at least {runs_text(successes_needed(alpha))} success "
            f"runs to calibrate on, got {n}{smallest}"
        )
    return float(np.nextafter(values[rank - 1], np.float32(np.inf)))


#: The spread report's tighter bound on the 95 % quantile of the realised FPR: α + SPREAD_MARGIN.
SPREAD_MARGIN: Final[float] = 0.02
#: The quantiles of the realised FPR `fpr_spread` reports.
SPREAD_LEVELS: Final[tuple[float, float]] = (0.05, 0.95)
_MAX_RUNS: Final[int] = 10_000_000  # `runs_for_bound` gives up beyond this (a bound a hair above α)


def binomial_tail(trials: int, p: float, at_least: int) -> float:
    """P(Binomial(trials, p) ≥ at_least), summed in log space (exact up to rounding for any size)."""
    if at_least <= 0:
        return 1.0
    if at_least > trials or p <= 0.0:
        return 0.0
    if p >= 1.0:
        return 1.0
    log_factorial = np.concatenate(([0.0], np.cumsum(np.log(np.arange(1, trials + 1, dtype=np.float64)))))
    j = np.arange(at_least, trials + 1)
    log_pmf = (
        log_factorial[trials]
        - log_factorial[j]
        - log_factorial[trials - j]
        + j * math.log(p)
        + (trials - j) * math.log1p(-p)
    )
    top = float(log_pmf.max())
    return min(1.0, math.exp(top) * float(np.exp(log_pmf - top).sum()))


def beta_cdf(x: float, a: int, b: int) -> float:
    """P(Beta(a, b) ≤ x) for integer a, b ≥ 1: P(Binomial(a+b−1, x) ≥ a)."""
    return binomial_tail(a + b - 1, min(max(x, 0.0), 1.0), a)


def beta_quantile(q: float, a: int, b: int) -> float:
    """The q-quantile of Beta(a, b) (integer a, b ≥ 1), by bisection on its CDF to 1e-10."""
    low, high = 0.0, 1.0
    while high - low > 1e-10:
        middle = (low + high) / 2
        low, high = (middle, high) if beta_cdf(middle, a, b) < q else (low, middle)
    return (low + high) / 2


def realised_fpr_parameters(successes: int, alpha: float) -> tuple[int, int]:
    """(a, b) with the realised FPR of n = `successes` calibration runs at level α ~ Beta(a, b):
    a = n+1−k, b = k (k = `conformal_rank`). DataError when n runs allow no threshold at α."""
    rank = conformal_rank(successes, alpha)
    if successes < 1 or rank > successes:
        raise DataError(
            f"{successes} calibration runs allow no threshold at α = {alpha:g} "
            f"(at least {runs_text(successes_needed(alpha))} needed)"
        )
    return successes + 1 - rank, rank


def _within(successes: int, alpha: float, bound: float, level: float) -> bool:
    """Whether the `level` quantile of the realised FPR of `successes` runs is ≤ `bound`."""
    a, b = realised_fpr_parameters(successes, alpha)
    return beta_cdf(bound, a, b) >= level


def runs_for_bound(alpha: float, bound: float, *, level: float = SPREAD_LEVELS[1]) -> int | None:
    """The fewest calibration runs n from which on (every n′ ≥ n) the `level` quantile of the realised
    FPR at α is ≤ `bound` (> α); None beyond ten million runs.

    Within runs of one a = n+1−k the quantile falls as n grows, and it jumps up where a grows (where
    (n+1)α passes an integer): those block starts are the worst n of each block and fall with n, so
    the answer is the first good n of the block before the first good block start."""
    check_target_fpr(alpha)
    if not alpha < bound < 1.0:
        raise SettingError(
            f"the bound on the realised FPR must lie in (α, 1) = ({alpha:g}, 1), got {bound:g}"
        )

    least = successes_needed(alpha)

    def block_start(a: int) -> int:  # the smallest n whose a = n+1−k is `a`
        n = max(math.ceil(a / alpha) - 3, least)
        while n + 1 - conformal_rank(n, alpha) < a:
            n += 1
        return n

    def good(a: int) -> bool:
        return _within(block_start(a), alpha, bound, level)

    first = least + 1 - conformal_rank(least, alpha)
    if good(first):
        return block_start(first)
    bad, step = first, 1
    while not good(first + step):  # gallop over block starts
        if block_start(first + step) > _MAX_RUNS:
            return None
        bad, step = first + step, 2 * step
    found = first + step
    while found - bad > 1:  # the first good block start lies in (bad, found]
        middle = (found + bad) // 2
        found, bad = (middle, bad) if good(middle) else (found, middle)
    low, high = block_start(found - 1), block_start(found)  # the block before may end good
    while low < high:
        middle = (low + high) // 2
        low, high = (low, middle) if _within(middle, alpha, bound, level) else (middle + 1, high)
    return low


@dataclass(frozen=True)
class FprSpread:
    """How far the test FPR of one calibration set can stray from α: the realised FPR's quantiles."""

    alpha: float
    successes: int  # n calibration runs
    mean: float  # (n+1−k)/(n+1) ≤ α: the promise on average over calibration sets
    low: float  # its SPREAD_LEVELS[0] quantile
    high: float  # its SPREAD_LEVELS[1] quantile
    bound: float  # α + SPREAD_MARGIN
    runs_for_bound: int | None  # runs from which on the SPREAD_LEVELS[1] quantile is ≤ bound

    def to_dict(self) -> dict[str, Any]:
        return {
            "successes": self.successes,
            "levels": list(SPREAD_LEVELS),
            "mean": round(self.mean, 6),
            "low": round(self.low, 6),
            "high": round(self.high, 6),
            "bound": round(self.bound, 6),
            "runs_for_bound": self.runs_for_bound,
        }

    def to_text(self) -> str:
        """One line: the range, and how many runs would tighten it."""
        low, high = (f"{100 * q:g}" for q in SPREAD_LEVELS)
        more = (
            f"{self.runs_for_bound} runs would keep the {high} % quantile ≤ {100 * self.bound:.1f} % (α + "
            f"{100 * SPREAD_MARGIN:g} points)"
            if self.runs_for_bound is not None
            else f"no number of runs up to {_MAX_RUNS} keeps it ≤ {100 * self.bound:.1f} %"
        )
        return (
            f"with {self.successes} calibration runs the test FPR at α = {100 * self.alpha:.3g} % lies in "
            f"{100 * self.low:.1f}–{100 * self.high:.1f} % ({low}–{high} % of calibration sets; mean "
            f"{100 * self.mean:.1f} %); {more}"
        )


def fpr_spread(successes: int, alpha: float, *, margin: float = SPREAD_MARGIN) -> FprSpread:
    """The realised FPR's range for `successes` calibration runs at level α, and the runs for α + margin."""
    a, b = realised_fpr_parameters(successes, alpha)
    bound = alpha + margin
    return FprSpread(
        alpha=alpha,
        successes=successes,
        mean=a / (a + b),
        low=beta_quantile(SPREAD_LEVELS[0], a, b),
        high=beta_quantile(SPREAD_LEVELS[1], a, b),
        bound=bound,
        runs_for_bound=runs_for_bound(alpha, bound) if bound < 1.0 else None,
    )


def empirical_fpr(peaks: Sequence[float], threshold: float) -> float:
    """The share of these peak scores that reach the threshold (that would fire: `reaches`)."""
    values = np.asarray(peaks, dtype=np.float32)
    return float(np.count_nonzero(reaches(values, np.float32(threshold)))) / max(values.size, 1)


def auc(failure_peaks: Sequence[float], success_peaks: Sequence[float]) -> float:
    """Area under the ROC curve of peak scores: P(failure peak > success peak), ties count half."""
    positives = np.asarray(failure_peaks, dtype=np.float64)
    negatives = np.asarray(success_peaks, dtype=np.float64)
    if positives.size == 0 or negatives.size == 0:
        return float("nan")
    positives = np.nan_to_num(positives, nan=-np.inf)
    negatives = np.nan_to_num(negatives, nan=-np.inf)
    greater = (positives[:, None] > negatives[None, :]).sum()
    ties = (positives[:, None] == negatives[None, :]).sum()
    return float((greater + 0.5 * ties) / (positives.size * negatives.size))


#: Bootstrap resamples behind `auc_interval`, and the interval's coverage.
AUC_DRAWS: Final[int] = 2000
AUC_LEVEL: Final[float] = 0.95
#: Runs of each kind a bootstrap interval needs: resampling one run always draws that run, and the
#: interval would claim a certainty (e.g. [0.00, 0.00]) that one run cannot give.
AUC_MIN_RUNS: Final[int] = 2


def auc_interval(
    failure_peaks: Sequence[float],
    success_peaks: Sequence[float],
    *,
    draws: int = AUC_DRAWS,
    level: float = AUC_LEVEL,
    seed: int = 0,
) -> tuple[float, float] | None:
    """The `level` percentile bootstrap interval of `auc`: failure and success runs resampled separately
    (`draws` times, from a fixed seed: the same peaks give the same interval); None with fewer than
    AUC_MIN_RUNS runs of either kind (it cannot be estimated)."""
    positives = np.nan_to_num(np.asarray(failure_peaks, dtype=np.float64), nan=-np.inf)
    negatives = np.nan_to_num(np.asarray(success_peaks, dtype=np.float64), nan=-np.inf)
    if positives.size < AUC_MIN_RUNS or negatives.size < AUC_MIN_RUNS:
        return None
    wins = (positives[:, None] > negatives[None, :]) + 0.5 * (positives[:, None] == negatives[None, :])
    rng = np.random.default_rng(seed)
    # a resample is a count per run; its AUC is the count-weighted mean of the pairwise wins
    picked_positives = rng.multinomial(positives.size, np.full(positives.size, 1.0 / positives.size), draws)
    picked_negatives = rng.multinomial(negatives.size, np.full(negatives.size, 1.0 / negatives.size), draws)
    resampled = ((picked_positives @ wins) * picked_negatives).sum(axis=1) / (positives.size * negatives.size)
    tail = 100 * (1.0 - level) / 2
    low, high = np.percentile(resampled, [tail, 100 - tail])
    return float(low), float(high)
