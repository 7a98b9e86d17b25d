"""The result of an evaluation: per-trajectory scores, the paper's tables and both rules, as JSON and Markdown."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from robofailring.calibration.bands import NONE, SHIFT
from robofailring.data.grounding import Vocabulary, failure_type
from robofailring.data.model import Skipped
from robofailring.detection.config import DEFAULT_STRIDE
from robofailring.detection.detector import (
    DetectionTrace,
)
from robofailring.detection.rules import ScoringRule
from robofailring.evaluation.blame import blame_markdown, false_alarm_entries
from robofailring.evaluation.growth import GrowthPoint, growth_markdown
from robofailring.evaluation.markdown import markdown_text, skipped_inputs_markdown
from robofailring.evaluation.metrics import (
    PAPER_DELTAS,
    Rates,
    ScoredTrajectory,
    fine_grid,
    json_number,
    rates,
    sweep,
    timeliness,
)
from robofailring.evaluation.modalities import ModalityResult, modalities_dict, modalities_markdown
from robofailring.evaluation.per_rule import (
    MARKDOWN_HEADER,
    RuleResult,
    onset_markdown,
    pct,
    scored_by_rule,
    shortfall_markdown,
    spread_markdown,
)
from robofailring.memory.entry import END, failure_frames_note
from robofailring.memory.pairs import CONCAT
from robofailring.outputs import EVALUATION_FORMAT

if TYPE_CHECKING:
    from robofailring.evaluation.folds import CrossValidation


@dataclass
class EvaluationResult:
    """Everything the evaluation measured, for the tables, the JSON file and the summary recording."""

    name: str
    encoder: str
    memory: str
    k: int
    operating_delta: float
    calibrated: bool
    views: list[str]
    scored: list[ScoredTrajectory] = field(repr=False)
    traces: dict[str, DetectionTrace] = field(repr=False)
    skipped_unknown_task: list[str]
    latency_ms: dict[str, float]
    skipped_too_short: list[str] = field(default_factory=list)
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the data not read
    stride: int = DEFAULT_STRIDE
    rules: dict[str, RuleResult] = field(default_factory=dict)  # both rules at their thresholds
    # per rule: the cameras alone, the signals alone and both, each at its own threshold (evaluation.modalities)
    modalities: dict[str, dict[str, ModalityResult]] = field(default_factory=dict)
    target_fpr: float | None = None
    deployment_successes: int = 0
    band: str = NONE  # the time-indexed band the rules beyond the paper's were judged on
    vocabulary: Vocabulary | None = field(default=None, repr=False)  # the memory's own failure symbols
    growth: list[GrowthPoint] = field(default_factory=list)  # `evaluate --growth`: the learning curve
    failure_frames: str = END  # the memory's failure frames: `end` (the paper's) or `dense` (memory.entry)
    pairing: str = CONCAT  # the memory's pairing: `concat` (the paper's) or `change` (memory.pairs)
    uncalibrated: list[str] = field(default_factory=list)  # rules too few training successes could calibrate
    cross_validation: CrossValidation | None = None  # `evaluate --folds`: every labelled run, pooled
    paper_rates: list[Rates] = field(init=False)
    curve: list[Rates] = field(init=False)

    def __post_init__(self) -> None:
        self.paper_rates = sweep(self.scored, PAPER_DELTAS)
        self.curve = sweep(self.scored, fine_grid(self.scored))

    @property
    def failures(self) -> int:
        return sum(t.is_failure for t in self.scored)

    @property
    def successes(self) -> int:
        return sum(not t.is_failure for t in self.scored)

    @property
    def fpr_guarantee(self) -> bool:
        """Whether every rule's threshold was calibrated at the asked α (False: too few training successes,
        some rule fell back to a larger α or could not be calibrated)."""
        asked = self.target_fpr
        return not self.uncalibrated and all(
            asked is None or r.level is None or r.level <= asked + 1e-12 for r in self.rules.values()
        )

    def rule_trace(self, key: str, rule: ScoringRule) -> DetectionTrace:
        """A test trajectory's trace judged by `rule` at its evaluated threshold."""
        return self.traces[key].with_rule(rule, self.rules[rule.name].threshold)

    def rule_scored(self, rule: ScoringRule) -> list[ScoredTrajectory]:
        """The test trajectories with `rule`'s score (S_t or C_t) per view."""
        return scored_by_rule(self.traces, {t.key: t for t in self.scored}, rule)

    def per_type_recall(
        self, delta: float, scored: Sequence[ScoredTrajectory] | None = None
    ) -> dict[str, Rates]:
        """Recall per failure type at `delta` (of `scored`: another rule's scores; default the paper's)."""
        scored = self.scored if scored is None else scored
        words = self.vocabulary
        types = sorted({failure_type(t.symbol, words) for t in scored if t.is_failure and t.symbol})
        return {
            kind: rates([t for t in scored if t.is_failure and failure_type(t.symbol, words) == kind], delta)
            for kind in types
        }

    def view_ablation(
        self, delta: float, scored: Sequence[ScoredTrajectory] | None = None
    ) -> dict[str, Rates]:
        scored = self.scored if scored is None else scored
        views = dict.fromkeys([*self.views, *(view for t in scored for view in t.similarity)])  # signals too
        ablation = {view: rates(scored, delta, [view]) for view in views}
        ablation["fusion"] = rates(scored, delta)
        return ablation

    def rule_charts(self, rule: ScoringRule, rate_row: Callable[[Rates], dict[str, Any]]) -> dict[str, Any]:
        """A rule's own sweep, recall per type and per view, and detection progress at its threshold."""
        scored = self.rule_scored(rule)
        threshold = self.rules[rule.name].threshold
        counts, edges = timeliness(scored, threshold).histogram()
        return {
            "operating_threshold": threshold,
            "sweep": [rate_row(r) for r in sweep(scored, fine_grid(scored))],
            "recall_per_type": {k: rate_row(v) for k, v in self.per_type_recall(threshold, scored).items()},
            "view_ablation": {k: rate_row(v) for k, v in self.view_ablation(threshold, scored).items()},
            "progress_histogram": {"threshold": threshold, "counts": counts, "edges": edges},
        }

    def false_alarms(self, delta: float) -> list[ScoredTrajectory]:
        return [t for t in self.scored if not t.is_failure and t.t_det(delta) is not None]

    def misses(self, delta: float) -> list[ScoredTrajectory]:
        return [t for t in self.scored if t.is_failure and t.t_det(delta) is None]

    def false_alarm_entries(self, delta: float) -> list[dict[str, Any]]:
        """Memory entries that were the top neighbour at a false alarm, most culpable first."""
        return false_alarm_entries(self.false_alarms(delta), self.traces, delta)

    def to_dict(self) -> dict[str, Any]:
        delta = self.operating_delta
        time_at = timeliness(self.scored, delta)
        counts, edges = time_at.histogram()

        def rate_row(r: Rates) -> dict[str, Any]:
            return {
                "delta": r.delta,
                "recall": json_number(r.recall),
                "fpr": json_number(r.fpr),
                "tp": r.tp,
                "fn": r.fn,
                "fp": r.fp,
                "tn": r.tn,
            }

        return {
            "format": EVALUATION_FORMAT,  # what tells a re-run this file is its own (outputs.check_own_files)
            "name": self.name,
            "encoder": self.encoder,
            "memory": self.memory,
            "failure_frames": self.failure_frames,
            "pairing": self.pairing,
            "k": self.k,
            "operating_delta": delta,
            "calibrated": self.calibrated,
            "failures": self.failures,
            "successes": self.successes,
            "skipped_unknown_task": self.skipped_unknown_task,
            "skipped_too_short": self.skipped_too_short,
            "skipped_inputs": [skipped.to_dict() for skipped in self.skipped_inputs],
            "stride": self.stride,
            "paper_deltas": [rate_row(r) for r in self.paper_rates],
            "sweep": [rate_row(r) for r in self.curve],
            "timeliness": {
                str(d): {
                    "detected_failures": timeliness(self.scored, d).count,
                    "mean_progress": json_number(timeliness(self.scored, d).mean_progress),
                    "median_progress": json_number(timeliness(self.scored, d).median_progress),
                    "mean_saving": json_number(timeliness(self.scored, d).mean_saving),
                    "median_saving": json_number(timeliness(self.scored, d).median_saving),
                }
                for d in (*PAPER_DELTAS, delta)
            },
            "progress_histogram": {
                "delta": delta,
                "counts": counts,
                "edges": edges,
                "values": list(time_at.progress),
            },
            "recall_per_type": {k: rate_row(v) for k, v in self.per_type_recall(delta).items()},
            "view_ablation": {k: rate_row(v) for k, v in self.view_ablation(delta).items()},
            "latency_ms": self.latency_ms,
            "target_fpr": self.target_fpr,
            "deployment_successes": self.deployment_successes,
            "band": self.band,
            **({"growth": [point.to_dict() for point in self.growth]} if self.growth else {}),
            "fpr_guarantee": self.fpr_guarantee,
            "uncalibrated_rules": self.uncalibrated,
            "cross_validation": self.cross_validation.to_dict()
            if self.cross_validation is not None
            else None,
            "rules": {
                name: result.to_dict() | self.rule_charts(result.rule, rate_row)
                for name, result in self.rules.items()
            },
            "modalities": modalities_dict(self.modalities),
            "false_alarms": [
                {"key": t.key, "t_det": t.t_det(delta), "length": t.length} for t in self.false_alarms(delta)
            ],
            "misses": [
                {
                    "key": t.key,
                    "symbol": t.symbol,
                    "peak": json_number(float(t.peak())),
                    "length": t.length,
                }
                for t in self.misses(delta)
            ],
            "false_alarm_entries": self.false_alarm_entries(delta),
            "trajectories": [
                {
                    "key": t.key,
                    "task": t.task,
                    "symbol": t.symbol,
                    "failure": t.is_failure,
                    "length": t.length,
                    "t_det": t.t_det(delta),
                    "peak": json_number(float(t.peak())),
                }
                for t in self.scored
            ],
        }

    def to_markdown(self) -> str:
        delta = self.operating_delta
        lines = [
            f"## {markdown_text(self.name)} — encoder {markdown_text(self.encoder, code=True)}, K = {self.k}, "
            f"{self.failure_frames} failure memory, "
            f"{self.pairing} pairing",
            "",
            f"{self.failures} failure and {self.successes} success test trajectories; memory "
            f"{markdown_text(self.memory, code=True)} "
            f"({failure_frames_note(self.failure_frames)}); "
            f"operating δ = {delta:.4f} ({'calibrated' if self.calibrated else 'paper default'}).",
            "",
            *self._rules_markdown(),
            *growth_markdown(self.growth),
            "| δ | Recall (%) | FPR (%) | TP | FN | FP | TN | mean T_s (%) | median progress (%) |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        shown = list(self.paper_rates)
        if all(abs(r.delta - delta) > 1e-9 for r in shown):
            shown.append(rates(self.scored, delta))
        for r in shown:
            t = timeliness(self.scored, r.delta)
            lines.append(
                f"| {r.delta:.4g} | {pct(r.recall)} | {pct(r.fpr)} | {r.tp} | {r.fn} | {r.fp} | {r.tn} | "
                f"{pct(t.mean_saving)} | {pct(t.median_progress)} |"
            )
        time_at = timeliness(self.scored, delta)
        lines += [
            "",
            f"Timeliness at δ = {delta:.4g}: {time_at.count} detected failures, mean detection progress "
            f"{pct(time_at.mean_progress)} %, median {pct(time_at.median_progress)} %, "
            f"temporal saving T_s mean {pct(time_at.mean_saving)} %, median {pct(time_at.median_saving)} %.",
            "",
            "| failure type | Recall (%) | detected / total |",
            "|---|---:|---:|",
        ]
        for kind, r in self.per_type_recall(delta).items():
            lines.append(f"| {markdown_text(kind)} | {pct(r.recall)} | {r.tp} / {r.tp + r.fn} |")
        lines += ["", "| views | Recall (%) | FPR (%) |", "|---|---:|---:|"]
        for view, r in self.view_ablation(delta).items():
            lines.append(f"| {markdown_text(view)} | {pct(r.recall)} | {pct(r.fpr)} |")
        lines += [
            "",
            f"Per-frame latency ({len(self.views)} views): encoder {self.latency_ms.get('encode', float('nan')):.2f} ms, "
            f"retrieval {self.latency_ms.get('retrieval', float('nan')):.3f} ms, "
            f"total {self.latency_ms.get('total', float('nan')):.2f} ms.",
        ]
        lines += blame_markdown(self.false_alarm_entries(delta))
        if self.skipped_too_short:
            lines += [
                "",
                f"Skipped {len(self.skipped_too_short)} test trajectories with no view of 2 or more frames.",
            ]
        lines += skipped_inputs_markdown(self.skipped_inputs)
        if self.stride > 1:
            lines += [
                "",
                f"One frame in {self.stride} scored (frame numbers, t_det and T_s are original frames).",
            ]
        if self.skipped_unknown_task:
            lines += [
                "",
                f"Skipped {len(self.skipped_unknown_task)} test trajectories whose task has no memory entry.",
            ]
        return "\n".join(lines)

    def _rules_markdown(self) -> list[str]:
        if not self.rules:
            return []
        deployed = (
            f" {self.deployment_successes} success run(s) per task from the test data joined the success "
            "memory (deployment successes) and are not tested."
            if self.deployment_successes
            else ""
        )
        banded = (
            f" Every rule's threshold but the paper's δ applies to the score corrected per frame index by the "
            f"calibration successes' {'mean' if self.band == SHIFT else 'mean and spread'} (band `{self.band}`)."
            if self.band != NONE
            else ""
        )
        return [
            "Every scoring rule, each calibrated on the training successes (split conformal, each run's own "
            f"episode left out):{deployed}{banded}",
            "",
            MARKDOWN_HEADER,
            *(result.markdown_row(self.target_fpr) for result in self.rules.values()),
            *modalities_markdown(self.modalities),
            *shortfall_markdown(
                list(self.rules.values()),
                self.target_fpr,
                left_out=self.uncalibrated,
                folds=self.cross_validation is not None,
            ),
            *spread_markdown(list(self.rules.values())),
            *onset_markdown(list(self.rules.values())),
            *(self.cross_validation.to_markdown() if self.cross_validation is not None else []),
            "",
            "The tables below are the paper rule (S_t ≥ δ).",
            "",
        ]
