"""Every scoring rule measured on the same replays: threshold, recall, FPR, T_s and peak-score AUC."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from robofailring.detection.conformal import FprSpread, auc
from robofailring.detection.detector import DetectionTrace
from robofailring.detection.rules import ScoringRule
from robofailring.evaluation.metrics import ScoredTrajectory, json_number, rates, timeliness
from robofailring.evaluation.onset import ONSET_HEADER, OnsetDelay, onset_delay


@dataclass(frozen=True)
class RuleResult:
    """One rule at one threshold over the test set."""

    rule: ScoringRule
    threshold: float
    calibrated: bool  # conformal threshold from training successes (else the default/stored one)
    tp: int
    fn: int
    fp: int
    tn: int
    ts_mean: float  # mean T_s = 1 − t_det/L over detected failures
    ts_median: float
    auc: float  # peak score, failures vs successes
    frame0_success_alarms: int  # success runs whose alarm is at frame 0
    false_alarms: tuple[str, ...] = ()  # keys of the success runs that fired
    misses: tuple[str, ...] = ()  # keys of the failures that did not
    spread: FprSpread | None = None  # calibrated here: how far its test FPR can stray from α
    onset: OnsetDelay | None = None  # alarms against the failures' known onsets

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else float("nan")

    @property
    def fpr(self) -> float:
        return self.fp / (self.fp + self.tn) if self.fp + self.tn else float("nan")

    def to_dict(self) -> dict[str, Any]:
        return {
            "symbol": self.rule.symbol,
            "score_name": self.rule.score_name,
            "threshold": self.threshold,
            "calibrated": self.calibrated,
            "recall": json_number(self.recall),
            "fpr": json_number(self.fpr),
            "tp": self.tp,
            "fn": self.fn,
            "fp": self.fp,
            "tn": self.tn,
            "ts_mean": json_number(self.ts_mean),
            "ts_median": json_number(self.ts_median),
            "auc": json_number(self.auc),
            "frame0_success_alarms": self.frame0_success_alarms,
            "false_alarms": list(self.false_alarms),
            "misses": list(self.misses),
            "fpr_spread": self.spread.to_dict() if self.spread is not None else None,
            "onset": self.onset.to_dict() if self.onset is not None else None,
        }

    def markdown_row(self, target_fpr: float | None) -> str:
        target = "—" if target_fpr is None or not self.calibrated else f"{100 * target_fpr:g}"
        return (
            f"| {self.rule.name} | {self.rule.symbol} = {self.threshold:.4f} | {target} | {_pct(self.recall)} | "
            f"{_pct(self.fpr)} | {self.tp} | {self.fn} | {self.fp} | {self.tn} | {_pct(self.ts_mean)} | "
            f"{self.auc:.3f} |"
        )


MARKDOWN_HEADER = (
    "| rule | threshold | target FPR (%) | Recall (%) | FPR (%) | TP | FN | FP | TN | mean T_s (%) | AUC |\n"
    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
)


def scored_by_rule(
    traces: Mapping[str, DetectionTrace], labels: Mapping[str, ScoredTrajectory], rule: ScoringRule
) -> list[ScoredTrajectory]:
    """The test trajectories with the rule's judged per-view score (band-corrected when it has a band) in
    place of S_t."""
    scored = []
    for key, base in labels.items():
        scored.append(replace(base, similarity=traces[key].judged_scores_of(rule)))
    return scored


def evaluate_rule(
    scored: Sequence[ScoredTrajectory],
    rule: ScoringRule,
    threshold: float,
    *,
    calibrated: bool,
    spread: FprSpread | None = None,
) -> RuleResult:
    """Counts, T_s and AUC of one rule at `threshold` on trajectories scored by that rule."""
    at = rates(scored, threshold)
    time_at = timeliness(scored, threshold)
    failures = [float(t.scores().max()) for t in scored if t.is_failure]
    successes = [float(t.scores().max()) for t in scored if not t.is_failure]
    return RuleResult(
        rule=rule,
        threshold=threshold,
        calibrated=calibrated,
        tp=at.tp,
        fn=at.fn,
        fp=at.fp,
        tn=at.tn,
        ts_mean=time_at.mean_saving,
        ts_median=time_at.median_saving,
        auc=auc(failures, successes),
        frame0_success_alarms=sum(1 for t in scored if not t.is_failure and t.t_det(threshold) == 0),
        false_alarms=tuple(t.key for t in scored if not t.is_failure and t.t_det(threshold) is not None),
        misses=tuple(t.key for t in scored if t.is_failure and t.t_det(threshold) is None),
        spread=spread,
        onset=onset_delay(scored, threshold),
    )


def onset_markdown(results: Sequence[RuleResult]) -> list[str]:
    """Each rule's alarms against the failures' onsets, or a line saying no onset is known."""
    onsets = [(result, result.onset) for result in results if result.onset is not None]
    if not onsets:
        return []
    if not any(onset.known for _, onset in onsets):
        return [
            "",
            "No failure run has a known onset (`onset_frame`): detection delay and premature alarms not measured.",
        ]
    return [
        "",
        "Alarms against the failure's onset (its first frame of the fault; delays over the alarms at or after it):",
        "",
        ONSET_HEADER,
        *(f"| {result.rule.name} {onset.markdown_cells()}" for result, onset in onsets),
    ]


def spread_markdown(results: Sequence[RuleResult]) -> list[str]:
    """The FPR promise beside α: one line per number of calibration runs the rules were set from."""
    spreads = {result.spread.successes: result.spread for result in results if result.spread is not None}
    if not spreads:
        return []
    rules = {
        n: ", ".join(r.rule.name for r in results if r.spread and r.spread.successes == n) for n in spreads
    }
    return [
        "",
        "The target FPR holds on average over calibration sets; one calibration set can miss it:",
        "",
        *(f"- {rules[n]}: {spread.to_text()}." for n, spread in sorted(spreads.items())),
    ]


def _pct(value: float) -> str:
    return "—" if math.isnan(value) else f"{100 * value:.2f}"
