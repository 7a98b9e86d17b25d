"""Split-conformal calibration of a rule's threshold, and the peak-score AUC.

With n success runs' peak scores, the threshold sits just above the ⌈(n+1)(1−α)⌉-th smallest, so a
new exchangeable success run fires with probability ≤ α.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from robofailring.errors import DataError, SettingError


def check_target_fpr(target_fpr: float) -> float:
    """A target false-positive rate α for (conformal) calibration: within (0, 1) (SettingError otherwise)."""
    if not 0.0 < target_fpr < 1.0:
        raise SettingError(f"target FPR must be in (0, 1), got {target_fpr}")
    return target_fpr


def successes_needed(alpha: float) -> int:
    """The fewest success runs for which a conformal threshold at level α exists: ⌈1/α − 1⌉."""
    return max(math.ceil(1.0 / alpha - 1.0 - 1e-9), 1)


def smallest_target_fpr(successes: int) -> float:
    """The smallest α that `successes` calibration runs allow: 1/(n+1) (n ≥ 1/α − 1)."""
    return 1.0 / (successes + 1)


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
    rank = math.ceil((n + 1) * (1.0 - alpha) - 1e-9)
    if n == 0 or rank > n:
        smallest = f"; the smallest α these {n} runs allow is {smallest_target_fpr(n):.4g}" if n else ""
        raise DataError(
            f"a guaranteed false-positive rate of {alpha:g} needs at least {successes_needed(alpha)} success "
            f"runs to calibrate on, got {n}{smallest}"
        )
    return float(np.nextafter(values[rank - 1], np.float32(np.inf)))


def empirical_fpr(peaks: Sequence[float], threshold: float) -> float:
    """The share of these peak scores that reach the threshold."""
    values = np.asarray(peaks, dtype=np.float32)
    return float(np.count_nonzero(values >= np.float32(threshold))) / max(values.size, 1)


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
