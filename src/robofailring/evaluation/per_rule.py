"""Every scoring rule measured on the same replays: threshold, recall, FPR, T_s and peak-score AUC (with its
bootstrap interval)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from robofailring.calibration.conformal import (
    AUC_LEVEL,
    AUC_MIN_RUNS,
    FprSpread,
    auc,
    auc_interval,
    runs_text,
    successes_needed,
)
from robofailring.detection.detector import DetectionTrace
from robofailring.detection.rules import ScoringRule
from robofailring.evaluation.metrics import ConfusionRates, ScoredTrajectory, json_number, rates, timeliness
from robofailring.evaluation.onset import ONSET_HEADER, OnsetDelay, onset_delay


@dataclass(frozen=True)
class RuleResult(ConfusionRates):
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
    level: float | None = (
        None  # calibrated here: the α its threshold was set to (above the asked one: too few runs)
    )
    auc_interval: tuple[float, float] | None = (
        None  # AUC's bootstrap interval (AUC_LEVEL); None without both kinds
    )
    best_recall: float = float("nan")  # the best recall any threshold reaches at a test FPR ≤ this one's

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
            "auc_interval": list(self.auc_interval) if self.auc_interval is not None else None,
            "best_recall": json_number(self.best_recall),
            "frame0_success_alarms": self.frame0_success_alarms,
            "false_alarms": list(self.false_alarms),
            "misses": list(self.misses),
            "fpr_spread": self.spread.to_dict() if self.spread is not None else None,
            "onset": self.onset.to_dict() if self.onset is not None else None,
            "target_fpr": self.level,
        }

    def markdown_row(self, target_fpr: float | None) -> str:
        target_fpr = self.level if self.level is not None else target_fpr
        target = "—" if target_fpr is None or not self.calibrated else f"{100 * target_fpr:.3g}"
        return (
            f"| {self.rule.name} | {self.rule.symbol} = {self.threshold:.4f} | {target} | {pct(self.recall)} | "
            f"{pct(self.fpr)} | {pct(self.best_recall)} | {self.tp} | {self.fn} | {self.fp} | {self.tn} | "
            f"{pct(self.ts_mean)} | {auc_cell(self.auc, self.auc_interval)} |"
        )


MARKDOWN_HEADER = (
    "| rule | threshold | target FPR (%) | Recall (%) | FPR (%) | best recall at that FPR (%) | TP | FN | FP | TN | "
    f"mean T_s (%) | AUC [{100 * AUC_LEVEL:g} % interval] |\n"
    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
)


def auc_cell(value: float, interval: tuple[float, float] | None) -> str:
    """An AUC with its bootstrap interval, for a table: `0.875 [0.62, 1.00]` (— when undefined; `[n/a]`
    when one kind has a single run and no interval can be estimated)."""
    if math.isnan(value):
        return "—"
    return f"{value:.3f}" + (f" [{interval[0]:.2f}, {interval[1]:.2f}]" if interval is not None else " [n/a]")


def peaks(scored: Sequence[ScoredTrajectory]) -> tuple[list[float], list[float]]:
    """The peak score (max over frames and views) of each failure run, and of each success run."""
    failures = [float(t.peak()) for t in scored if t.is_failure]
    successes = [float(t.peak()) for t in scored if not t.is_failure]
    return failures, successes


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
    level: float | None = None,
) -> RuleResult:
    """Counts, T_s and AUC (with its bootstrap interval) of one rule at `threshold` on trajectories scored
    by that rule; `level`: the α the threshold was calibrated to here."""
    at = rates(scored, threshold)
    time_at = timeliness(scored, threshold)
    failures, successes = peaks(scored)
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
        auc_interval=auc_interval(failures, successes),
        frame0_success_alarms=sum(1 for t in scored if not t.is_failure and t.t_det(threshold) == 0),
        false_alarms=tuple(t.key for t in scored if not t.is_failure and t.t_det(threshold) is not None),
        misses=tuple(t.key for t in scored if t.is_failure and t.t_det(threshold) is None),
        spread=spread,
        onset=onset_delay(scored, threshold),
        level=level,
        best_recall=best_recall(failures, successes, at.fpr),
    )


def best_recall(failures: Sequence[float], successes: Sequence[float], fpr: float) -> float:
    """The highest recall any threshold reaches with a test FPR ≤ `fpr` (the same test runs' peaks): what this
    threshold could have had, so what its calibration cost (NaN without failures)."""
    if not failures or math.isnan(fpr):
        return float("nan")
    normal = np.sort(np.asarray(successes, np.float64))
    allowed = math.floor(fpr * len(normal) + 1e-9)  # false alarms allowed
    # the lowest threshold with at most `allowed` successes at or above it: just above the (allowed+1)-th highest
    floor = (
        -np.inf if allowed >= len(normal) else float(np.nextafter(normal[len(normal) - 1 - allowed], np.inf))
    )
    return float(np.mean(np.asarray(failures, np.float64) >= floor))


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
        *(
            f"- {rules[n]}: {spread.to_text()}{top_peak_text(n, spread.alpha)}."
            for n, spread in sorted(spreads.items())
        ),
    ]


def runs_below_top(alpha: float) -> int:
    """The fewest calibration runs whose split-conformal threshold at α sits below their highest peak."""
    n = successes_needed(alpha)
    while math.ceil((n + 1) * (1 - alpha) - 1e-9) >= n:
        n += 1
    return n


def top_peak_text(runs: int, alpha: float) -> str:
    """Where `runs` calibration runs at α can only take the highest peak: said plainly, with how many would not."""
    if runs < successes_needed(alpha) or math.ceil((runs + 1) * (1 - alpha) - 1e-9) < runs:
        return ""
    return (
        f"; with {runs} runs the threshold is the highest calibration peak (one unusual success sets it): "
        f"{runs_text(runs_below_top(alpha))} runs would let it sit below the highest"
    )


def pct(value: float) -> str:
    """A rate in percent for a table (— when undefined)."""
    return "—" if math.isnan(value) else f"{100 * value:.2f}"


def shortfall_markdown(
    results: Sequence[RuleResult], asked: float | None, *, left_out: Sequence[str] = (), folds: bool = False
) -> list[str]:
    """What holds when the training successes were too few for the asked α: the plain statement that no
    FPR guarantee at α holds, the level each rule fell back to, the rules none of whose runs could be
    scored; empty when every rule was calibrated at α."""
    short = [r for r in results if asked is not None and r.level is not None and r.level > asked + 1e-12]
    if asked is None or not (short or left_out):
        return []
    by_level: dict[tuple[int, float], list[str]] = {}
    for result in short:
        runs = result.spread.successes if result.spread is not None else 0
        by_level.setdefault((runs, result.level or asked), []).append(result.rule.name)
    lines = [
        "",
        f"**No false-positive-rate guarantee holds here.** A guaranteed FPR of α = {100 * asked:g} % needs at "
        f"least {runs_text(successes_needed(asked))} training success runs to calibrate on, and there were fewer. "
        "Each threshold is set at the smallest α its runs allow (just above the highest calibration peak), "
        "so the recall and FPR in the table are what these test runs showed, not a promise:",
        "",
        *(
            f"- {', '.join(names)}: {runs} calibration run(s), α = {100 * level:.3g} %"
            for (runs, level), names in sorted(by_level.items())
        ),
        *(
            f"- {name}: none of the training success runs could be scored by it (their task holds nothing for "
            "it to compare them with once their own episode is left out): not calibrated, not in the table"
            for name in left_out
        ),
        "",
        f"The AUC (failure against success runs' peak scores, with its {100 * AUC_LEVEL:g} % bootstrap "
        f"interval; n/a with fewer than {AUC_MIN_RUNS} runs of a kind) needs no threshold"
        + (
            "; the cross-validation below pools every labelled run."
            if folds
            else "; for figures over every labelled run, cross-validate with `--folds loo` (or `--folds K`)."
        ),
    ]
    return lines
