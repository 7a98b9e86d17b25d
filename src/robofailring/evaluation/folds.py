"""Cross-validation over every labelled run of a dataset (`evaluate --folds K|loo`), for data too small to
hold out a test split worth the name: each fold's runs are judged by a memory built, and thresholds
calibrated, on the other folds' runs (at α, or the smallest α their success runs allow), and the
counts and peak scores are pooled over folds."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Final

from robofailring.calibration.conformal import AUC_LEVEL, auc, auc_interval, runs_text, successes_needed
from robofailring.calibration.job import RuleCalibration, available_rules, calibrate_rules
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.model import Trajectory
from robofailring.data.selection import DataSelection
from robofailring.data.splits import key_digest
from robofailring.detection.config import DetectorConfig
from robofailring.detection.detector import DetectionTrace, FailureDetector
from robofailring.detection.loader import detector_with
from robofailring.detection.rules import RULES, ScoringRule
from robofailring.encoders import CachedEncoder
from robofailring.errors import DataError, SettingError
from robofailring.evaluation.metrics import ConfusionRates, ScoredTrajectory, json_number, rates
from robofailring.evaluation.per_rule import auc_cell, pct, peaks
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.recipe import MemoryRecipe
from robofailring.progress import progress_bar

#: `--folds loo`: one fold per episode.
LEAVE_ONE_OUT: Final[str] = "loo"


@dataclass(frozen=True)
class FoldPlan:
    """How `evaluate --folds` cuts every labelled run of its data into folds."""

    count: int | None  # folds (≥ 2); None: one per episode (leave-one-episode-out)

    @classmethod
    def parse(cls, text: str) -> FoldPlan:
        """`loo` or a whole number ≥ 2; SettingError otherwise."""
        cleaned = text.strip().lower()
        if cleaned == LEAVE_ONE_OUT:
            return cls(None)
        if not cleaned.isdecimal() or int(cleaned) < 2:
            raise SettingError(f"--folds takes {LEAVE_ONE_OUT} or a whole number ≥ 2, got {text!r}")
        return cls(int(cleaned))

    def describe(self, folds: int) -> str:
        """In words, with the number of folds it gave."""
        if self.count is None:
            return f"leave-one-episode-out: {folds} folds of one run"
        return f"{folds} folds, failures and successes dealt evenly"

    def to_json(self) -> str | int:
        return LEAVE_ONE_OUT if self.count is None else self.count


@dataclass
class PooledRule(ConfusionRates):
    """One rule's counts and peak scores over every fold that could calibrate it."""

    rule: ScoringRule
    tp: int = 0
    fn: int = 0
    fp: int = 0
    tn: int = 0
    failure_peaks: list[float] = field(default_factory=list)
    success_peaks: list[float] = field(default_factory=list)
    levels: list[float] = field(default_factory=list)  # per fold that judged: the α its threshold was set to
    calibration_runs: list[int] = field(default_factory=list)  # per fold that judged: its success runs scored
    unjudged: int = 0  # runs of folds that could not calibrate this rule

    @property
    def judged(self) -> int:
        return self.tp + self.fn + self.fp + self.tn

    @property
    def auc(self) -> float:
        return auc(self.failure_peaks, self.success_peaks)

    @property
    def auc_interval(self) -> tuple[float, float] | None:
        return auc_interval(self.failure_peaks, self.success_peaks)

    def to_dict(self) -> dict[str, Any]:
        interval = self.auc_interval
        return {
            "judged": self.judged,
            "tp": self.tp,
            "fn": self.fn,
            "fp": self.fp,
            "tn": self.tn,
            "recall": json_number(self.recall),
            "fpr": json_number(self.fpr),
            "auc": json_number(self.auc),
            "auc_interval": list(interval) if interval is not None else None,
            "target_fpr": {"min": min(self.levels), "max": max(self.levels)} if self.levels else None,
            "calibration_runs": (
                {"min": min(self.calibration_runs), "max": max(self.calibration_runs)}
                if self.calibration_runs
                else None
            ),
            "unjudged": self.unjudged,
        }


@dataclass(frozen=True)
class CrossValidation:
    """The pooled figures of `evaluate --folds` and what they were computed from."""

    plan: FoldPlan
    folds: int
    target_fpr: float  # the α asked for
    failures: int  # labelled failure runs cross-validated
    successes: int  # labelled success runs cross-validated
    rules: dict[str, PooledRule]
    not_judged: dict[str, str]  # run key → why no fold judged it
    unlabelled: int  # runs with no outcome, left out

    @property
    def guaranteed(self) -> bool:
        """Whether every fold calibrated every rule at the asked α."""
        return all(
            level <= self.target_fpr + 1e-12 for pooled in self.rules.values() for level in pooled.levels
        )

    def _short_folds(self) -> int:
        """Folds that judged some rule above the asked α (too few success runs among the others)."""
        return max(
            (
                sum(level > self.target_fpr + 1e-12 for level in pooled.levels)
                for pooled in self.rules.values()
            ),
            default=0,
        )

    @property
    def plan_folds(self) -> int:
        """Folds that judged some rule (the most over the rules)."""
        return max((len(pooled.levels) for pooled in self.rules.values()), default=0)

    def to_dict(self) -> dict[str, Any]:
        return {
            "folds": self.plan.to_json(),
            "fold_count": self.folds,
            "target_fpr": self.target_fpr,
            "fpr_guarantee": self.guaranteed,
            "failures": self.failures,
            "successes": self.successes,
            "unlabelled": self.unlabelled,
            "not_judged": [{"key": key, "reason": reason} for key, reason in self.not_judged.items()],
            "rules": {name: pooled.to_dict() for name, pooled in self.rules.items()},
        }

    def to_markdown(self) -> list[str]:
        runs = self.failures + self.successes
        lines = [
            "",
            f"Cross-validation over every labelled run ({runs}: {self.failures} failure, {self.successes} success; "
            f"{self.plan.describe(self.folds)}): each fold's runs are judged by a memory built, and thresholds "
            f"calibrated at α = {100 * self.target_fpr:g} % or the smallest α their success runs allow, on the "
            "other folds' runs; counts and peak scores pooled over folds.",
            "",
            "| rule | runs judged | AUC ["
            + f"{100 * AUC_LEVEL:g} % interval] | Recall (%) | FPR (%) | TP | FN | "
            "FP | TN | α used (%) | calibration runs |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for name, pooled in self.rules.items():
            lines.append(
                f"| {name} | {pooled.judged} | {auc_cell(pooled.auc, pooled.auc_interval)} | {pct(pooled.recall)} | "
                f"{pct(pooled.fpr)} | {pooled.tp} | {pooled.fn} | {pooled.fp} | {pooled.tn} | "
                f"{_span([100 * level for level in pooled.levels], '.3g')} | {_span(pooled.calibration_runs, 'd')} |"
            )
        if not self.guaranteed:
            lines += [
                "",
                f"**No false-positive-rate guarantee holds for the cross-validation:** α = {100 * self.target_fpr:g} % needs "
                f"{runs_text(successes_needed(self.target_fpr))} success runs to calibrate on and some folds had fewer "
                f"({self._short_folds()} of {self.plan_folds} judged at a larger α), so the pooled FPR is what "
                "these runs showed at the α used, not a promise.",
            ]
        unjudged = {name: pooled.unjudged for name, pooled in self.rules.items() if pooled.unjudged}
        if unjudged:
            lines += [
                "",
                "Runs of folds whose other runs could not calibrate the rule (no success run scored): "
                + ", ".join(f"{name} {count}" for name, count in unjudged.items())
                + ".",
            ]
        if self.not_judged:
            shown = "; ".join(f"`{key}` ({reason})" for key, reason in list(self.not_judged.items())[:10])
            more = f" … and {len(self.not_judged) - 10} more" if len(self.not_judged) > 10 else ""
            lines += ["", f"Not judged ({len(self.not_judged)}): {shown}{more}."]
        if self.unlabelled:
            lines += ["", f"{self.unlabelled} run(s) without an outcome left out."]
        return lines


def assign_folds(runs: Sequence[Trajectory], plan: FoldPlan) -> list[list[Trajectory]]:
    """The folds: failures and successes each dealt in turn, in a fixed pseudo-random order (a hash of
    their key), so every fold holds both kinds as far as the counts allow; one run per fold for `loo`."""
    count = len(runs) if plan.count is None else plan.count
    if count > len(runs):
        raise DataError(f"--folds {count} needs at least {count} labelled runs, the data has {len(runs)}")
    ordered = sorted(runs, key=key_digest)
    dealt = [t for t in ordered if t.is_failure] + [t for t in ordered if not t.is_failure]
    folds: list[list[Trajectory]] = [[] for _ in range(count)]
    for position, trajectory in enumerate(dealt):
        folds[position % count].append(trajectory)
    return folds


def cross_validate(
    trajectories: Sequence[Trajectory],
    encoder: CachedEncoder,
    *,
    plan: FoldPlan,
    data: DataSelection,
    recipe: MemoryRecipe,
    success_memory: bool,
    detector: DetectorConfig,
    policy: ThresholdPolicy,
    stride: int,
) -> CrossValidation:
    """Every labelled run of `trajectories` (the whole of `data`) judged by a memory of the other folds of
    `plan` (made by `recipe`, with a success memory where `success_memory`), its rules on `detector`'s settings
    at thresholds `policy` sets on those folds' successes; pooled."""
    runs = [t for t in trajectories if t.outcome is not None]
    folds = assign_folds(runs, plan)
    vocabulary = data.read_vocabulary()
    pooled: dict[str, PooledRule] = {}
    not_judged: dict[str, str] = {}
    with progress_bar(total=len(folds), desc="cross-validating", unit="fold") as bar:
        for held_out in folds:
            bar.update(1)
            others = [t for fold in folds if fold is not held_out for t in fold]
            memory, _ = build_memories(
                others,
                encoder,
                provenance=Provenance(data=data.root, encoder=recipe.encoder),
                successes=success_memory,
                recipe=recipe,
                vocabulary=vocabulary,
            )
            judging = detector_with(detector, memory, encoder)
            rules = available_rules(judging)
            known = set(memory.tasks)
            successes = [t for t in others if not t.is_failure and t.task in known]
            found: dict[ScoringRule, RuleCalibration] = (
                calibrate_rules(
                    judging,
                    successes,
                    policy,
                    rules=rules,
                    stride=stride,
                    at_best=True,
                )
                if successes
                else {}
            )
            bands = {rule.name: c.band for rule, c in found.items() if c.band is not None}
            judging = detector_with(detector, memory, encoder, bands=bands)
            traces = _judge(judging, held_out, known, stride, not_judged)
            for rule in rules:
                into = pooled.setdefault(rule.name, PooledRule(rule))
                calibration = found.get(rule)
                if calibration is None:
                    into.unjudged += len(traces)
                    continue
                _pool(into, calibration, traces)
    return CrossValidation(
        plan=plan,
        folds=len(folds),
        target_fpr=policy.target_fpr,
        failures=sum(t.is_failure for t in runs),
        successes=sum(not t.is_failure for t in runs),
        rules={name: pooled[name] for name in RULES if name in pooled},
        not_judged=not_judged,
        unlabelled=len(trajectories) - len(runs),
    )


def _judge(
    detector: FailureDetector,
    held_out: Sequence[Trajectory],
    known: set[str],
    stride: int,
    not_judged: dict[str, str],
) -> list[tuple[Trajectory, DetectionTrace]]:
    """Each held-out run's trace; those that cannot be judged are noted in `not_judged` with the reason."""
    traces = []
    for trajectory in held_out:
        if trajectory.task not in known:
            not_judged[trajectory.key] = "its task has no run in the other folds"
            continue
        try:
            traces.append((trajectory, detector.run(trajectory, stride=stride, keep_queries=False)))
        except DataError:
            not_judged[trajectory.key] = "no view of 2+ frames"
    return traces


def _pool(
    into: PooledRule, calibration: RuleCalibration, traces: Sequence[tuple[Trajectory, DetectionTrace]]
) -> None:
    """Add one fold's runs, judged by `calibration`'s rule at its threshold, to the pooled figures."""
    rule = calibration.rule
    scored = [
        ScoredTrajectory.of(trajectory, trace.length, trace.judged_scores_of(rule))
        for trajectory, trace in traces
    ]
    counts = rates(scored, calibration.threshold)
    into.tp, into.fn, into.fp, into.tn = (
        into.tp + counts.tp,
        into.fn + counts.fn,
        into.fp + counts.fp,
        into.tn + counts.tn,
    )
    failures, successes = peaks(scored)
    into.failure_peaks += failures
    into.success_peaks += successes
    into.levels.append(calibration.target_fpr)
    into.calibration_runs.append(calibration.successes)


def _span(values: Sequence[float], spec: str) -> str:
    """`low–high` (one value when they agree; — without any)."""
    if not values:
        return "—"
    low, high = format(min(values), spec), format(max(values), spec)
    return low if low == high else f"{low}–{high}"
