"""The learning curve of an evaluation (`evaluate --growth 0,1,2,4`): the same test set judged as the
memory grows from the task's success runs alone (novelty) to 1, 2, 4, … labelled failures per task
and all of them (contrast), each level by its tasks' default rule at the same α; the few labelled failures a
level's memory holds (`labelled_failures`). The evaluations themselves are run by
`robofailring.evaluation.job.growth_curve`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from robofailring.data.model import Trajectory
from robofailring.data.splits import key_digest
from robofailring.detection.rules import default_rule
from robofailring.errors import SettingError
from robofailring.evaluation.metrics import json_number
from robofailring.evaluation.per_rule import RuleResult


@dataclass(frozen=True)
class GrowthPoint:
    """One level of the curve: labelled failures per task (None: all) and its default rule's result."""

    failures_per_task: int | None
    result: RuleResult

    @property
    def label(self) -> str:
        return "all" if self.failures_per_task is None else str(self.failures_per_task)

    def to_dict(self) -> dict[str, Any]:
        rule = self.result
        return {
            "failures_per_task": self.failures_per_task,
            "rule": rule.rule.name,
            "symbol": rule.rule.symbol,
            "threshold": rule.threshold,
            "recall": json_number(rule.recall),
            "fpr": json_number(rule.fpr),
            "ts_mean": json_number(rule.ts_mean),
            "auc": json_number(rule.auc),
        }


def parse_growth(text: str) -> tuple[int, ...]:
    """`0,1,2,4` → (0, 1, 2, 4); SettingError naming a part that is not a whole number ≥ 0."""
    levels = []
    for part in (p.strip() for p in text.split(",")):
        if not part.isdecimal():
            raise SettingError(
                f"--growth takes whole numbers ≥ 0 separated by commas (0,1,2,4), got {part!r}"
            )
        levels.append(int(part))
    return tuple(sorted(set(levels)))


def labelled_failures(trajectories: Sequence[Trajectory], per_task: int | None) -> list[Trajectory]:
    """The success runs and `per_task` failure runs of each task (None: all of them), the failures
    in a fixed pseudo-random order (a hash of their key), so the few that are labelled are of mixed types."""
    if per_task is None:
        return list(trajectories)
    kept: dict[str, int] = {}
    chosen = []
    for trajectory in sorted(trajectories, key=key_digest):
        if trajectory.is_failure:
            if kept.get(trajectory.task, 0) >= per_task:
                continue
            kept[trajectory.task] = kept.get(trajectory.task, 0) + 1
        chosen.append(trajectory)
    return chosen


def judged(rules: dict[str, RuleResult], *, failures: bool) -> RuleResult:
    """The result of the rule a level is judged by: contrast with failures, novelty without."""
    return rules[default_rule(successes=True, failures=failures).name]


def growth_markdown(points: Sequence[GrowthPoint]) -> list[str]:
    """The curve as a Markdown table (empty without points)."""
    if not points:
        return []
    rows = [
        f"| {p.label} | {p.result.rule.name} | {p.result.rule.symbol} = {p.result.threshold:.4f} | "
        f"{_pct(p.result.recall)} | {_pct(p.result.fpr)} | {_pct(p.result.ts_mean)} | {p.result.auc:.3f} |"
        for p in points
    ]
    return [
        "Learning curve: the memory grown from success runs only to every labelled failure, each level "
        "judged by its default rule at the same α:",
        "",
        "| labelled failures / task | rule | threshold | Recall (%) | FPR (%) | mean T_s (%) | AUC |",
        "|---:|---|---:|---:|---:|---:|---:|",
        *rows,
        "",
    ]


def _pct(value: float) -> str:
    return "—" if value != value else f"{100 * value:.2f}"
