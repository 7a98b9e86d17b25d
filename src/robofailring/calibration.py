"""Calibration with a guarantee (README, "Calibration with a guarantee"): δ and γ from success runs.

Each success run is replayed with its own episode hidden from both memories (leave-one-out), so
its frames never match themselves in the success memory; its peak score over frames and views is
one conformal score. The threshold of each rule is the split-conformal one of
`robofailring.scoring.conformal_threshold`, pooled over tasks.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from robofailring.data.model import Trajectory
from robofailring.detector import FailureDetector
from robofailring.errors import DataError
from robofailring.scoring import ScoreRule, conformal_threshold, empirical_fpr


@dataclass(frozen=True)
class RuleCalibration:
    """One rule's conformal threshold and what it achieved on the runs it was set from."""

    rule: ScoreRule
    threshold: float
    target_fpr: float
    achieved_fpr: float  # share of the calibration runs that reach the threshold (≤ α by construction)
    successes: int


def available_rules(detector: FailureDetector) -> list[ScoreRule]:
    """The rules this detector's memory supports: contrast needs success runs."""
    if detector.memory.successes is None:
        return [ScoreRule.PAPER]
    return [ScoreRule.PAPER, ScoreRule.CONTRAST]


def success_peaks(
    detector: FailureDetector,
    successes: Sequence[Trajectory],
    rules: Sequence[ScoreRule],
    *,
    progress: Callable[[int], None] | None = None,
    stride: int = 1,
) -> dict[ScoreRule, list[float]]:
    """Per rule, each success run's peak score, its episode left out of both memories.

    `stride` scores every N-th frame, as the runs the threshold will judge are scored."""
    peaks: dict[ScoreRule, list[float]] = {rule: [] for rule in rules}
    for trajectory in successes:
        with contextlib.suppress(DataError):  # no view with 2 frames: nothing to score
            trace = detector.run(trajectory, leave_one_out=True, stride=stride)
            for rule in rules:
                peaks[rule].append(float(trace.with_rule(rule, 0.0).max_score().max()))
        if progress is not None:
            progress(1)
    return peaks


def calibrate_rules(
    detector: FailureDetector,
    successes: Sequence[Trajectory],
    target_fpr: float,
    *,
    rules: Sequence[ScoreRule] | None = None,
    progress: Callable[[int], None] | None = None,
    stride: int = 1,
) -> dict[ScoreRule, RuleCalibration]:
    """The conformal threshold of every rule (default: all the memory supports) at level `target_fpr`."""
    chosen = list(rules) if rules is not None else available_rules(detector)
    peaks = success_peaks(detector, successes, chosen, progress=progress, stride=stride)
    calibrations = {}
    for rule, values in peaks.items():
        if not values:
            raise DataError(f"none of the {len(successes)} success trajectories has a view of 2+ frames")
        scored = [v for v in values if math.isfinite(v)]
        try:
            threshold = conformal_threshold(scored, target_fpr)
        except DataError as error:
            if len(scored) < len(values):
                raise DataError(
                    f"{error} ({len(values) - len(scored)} of the {len(values)} runs are the only success run of "
                    f"their task, so leaving their episode out leaves nothing to contrast them with)"
                ) from error
            raise
        calibrations[rule] = RuleCalibration(
            rule=rule,
            threshold=threshold,
            target_fpr=target_fpr,
            achieved_fpr=empirical_fpr(scored, threshold),
            successes=len(scored),
        )
    return calibrations
