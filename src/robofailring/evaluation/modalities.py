"""Every figure per modality (issue 51 item 3): the cameras alone, the robot's signals alone and both fused, side
by side, each calibrated on the same training successes with its own bands and threshold, so a user sees what
their robot's signals added (docs/evaluation.md, "Per modality").

A modality alone is judged as a detector of that modality judges (`--modality cameras|signals`): its views'
scores, corrected by the bands fitted on its own views' calibration scores, against its own split-conformal
threshold. The calibration scores are the ones the fused thresholds were set from (no run is replayed twice).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Final

import numpy as np

from robofailring.calibration.conformal import attainable_target_fpr, conformal_threshold
from robofailring.calibration.fusions import fusion_named, per_task_peaks
from robofailring.data.grounding import Vocabulary, failure_type
from robofailring.detection.band import NONE
from robofailring.detection.detector import DetectionTrace
from robofailring.detection.rules import PAPER, ScoringRule
from robofailring.errors import DataError
from robofailring.evaluation.metrics import ScoredTrajectory, json_number, rates
from robofailring.evaluation.per_rule import RuleResult, auc_cell, evaluate_rule, pct
from robofailring.memory.signals.modality import BOTH, CAMERAS, SIGNALS, SIGNALS_VIEW, judged_views

TASK: Final[str] = "task"


@dataclass(frozen=True)
class CalibrationScores:
    """What the fused thresholds were calibrated from: per rule, each training success's raw per-view scores (its
    episode left out), each run's task, the level, band kind, fusion and band scope asked."""

    runs: Mapping[ScoringRule, Sequence[Mapping[str, np.ndarray]]]
    tasks: Sequence[str]
    target_fpr: float
    band: str
    fusion: str
    band_scope: str


@dataclass(frozen=True)
class ModalityResult:
    """One modality's rule at its own threshold, and its recall per failure family."""

    modality: str  # cameras, signals or both
    result: RuleResult
    per_type: dict[str, tuple[int, int]]  # failure family: (detected, total)

    def to_dict(self) -> dict[str, Any]:
        result = self.result
        return {
            "threshold": result.threshold,
            "target_fpr": result.level,
            "recall": json_number(result.recall),
            "fpr": json_number(result.fpr),
            "tp": result.tp,
            "fn": result.fn,
            "fp": result.fp,
            "tn": result.tn,
            "ts_mean": json_number(result.ts_mean),
            "auc": json_number(result.auc),
            "best_recall": json_number(result.best_recall),
            "recall_per_type": {kind: {"detected": d, "total": n} for kind, (d, n) in self.per_type.items()},
        }


def _views(modality: str, run: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {view: run[view] for view in judged_views(run, modality)}


def _per_type(
    scored: Sequence[ScoredTrajectory], threshold: float, words: Vocabulary | None
) -> dict[str, Any]:
    failures = [t for t in scored if t.is_failure and t.symbol]
    kinds = sorted({failure_type(t.symbol, words) for t in failures})
    out = {}
    for kind in kinds:
        found = rates([t for t in failures if failure_type(t.symbol, words) == kind], threshold)
        out[kind] = (found.tp, found.tp + found.fn)
    return out


def modality_results(
    traces: Mapping[str, DetectionTrace],
    labels: Mapping[str, ScoredTrajectory],
    calibration: CalibrationScores,
    fused: Mapping[str, RuleResult],
    vocabulary: Vocabulary | None = None,
) -> dict[str, dict[str, ModalityResult]]:
    """Per rule name (the paper rule aside), the cameras alone, the signals alone and both (`fused`: the
    evaluation's own rows), each modality alone calibrated on `calibration`'s runs with its own bands. Empty
    where the test runs lack one of the modalities."""
    views = {view for trace in traces.values() for view in trace.scored_views}
    if SIGNALS_VIEW not in views or views == {SIGNALS_VIEW}:
        return {}
    out: dict[str, dict[str, ModalityResult]] = {}
    for rule, runs in calibration.runs.items():
        if rule is PAPER or rule.name not in fused:
            continue
        rows: dict[str, ModalityResult] = {}
        for modality in (CAMERAS, SIGNALS):
            found = _alone(modality, rule, runs, calibration, traces, labels)
            if found is not None:
                result, scored = found
                rows[modality] = ModalityResult(
                    modality, result, _per_type(scored, result.threshold, vocabulary)
                )
        both = [replace(labels[key], similarity=traces[key].judged_scores_of(rule)) for key in labels]
        rows[BOTH] = ModalityResult(
            BOTH, fused[rule.name], _per_type(both, fused[rule.name].threshold, vocabulary)
        )
        out[rule.name] = rows
    return out


def _alone(
    modality: str,
    rule: ScoringRule,
    runs: Sequence[Mapping[str, np.ndarray]],
    calibration: CalibrationScores,
    traces: Mapping[str, DetectionTrace],
    labels: Mapping[str, ScoredTrajectory],
) -> tuple[RuleResult, list[ScoredTrajectory]] | None:
    """`modality`'s rule calibrated on its own views of the calibration runs and judged on the test runs."""
    own = [_views(modality, run) for run in runs]
    kind = calibration.band
    peaks_of = fusion_named(calibration.fusion).peaks
    if calibration.band_scope == TASK:
        values, band = per_task_peaks(peaks_of, own, calibration.tasks, kind)
    else:
        values, band = peaks_of(own, kind, calibration.tasks)
    scored_peaks = [v for v in values if math.isfinite(v)]
    if not scored_peaks:
        return None
    try:
        level = attainable_target_fpr(len(scored_peaks), calibration.target_fpr)
        threshold = conformal_threshold(scored_peaks, level)
    except DataError:
        return None
    scored = []
    for key, base in labels.items():
        raw = _views(modality, traces[key].scores_of(rule))
        if band is not None and kind != NONE:
            bound = band.for_task(base.task)
            raw = {view: bound.correct(values, view) for view, values in raw.items()}
        scored.append(replace(base, similarity=raw))
    return evaluate_rule(scored, rule, threshold, calibrated=True, level=level), scored


def modalities_dict(found: Mapping[str, Mapping[str, ModalityResult]]) -> dict[str, dict[str, Any]]:
    """The JSON of `modality_results`: per rule, per modality."""
    return {name: {modality: row.to_dict() for modality, row in rows.items()} for name, rows in found.items()}


def modalities_markdown(found: Mapping[str, Mapping[str, ModalityResult]]) -> list[str]:
    """The per-modality table of every rule, with recall per failure family."""
    if not found:
        return []
    kinds = sorted({kind for rows in found.values() for row in rows.values() for kind in row.per_type})
    lines = [
        "",
        "Per modality: the cameras alone, the robot's signals alone and both fused, each calibrated on the same "
        "training successes with its own bands and threshold (recall per failure family: detected / total):",
        "",
        "| rule | modality | threshold | Recall (%) | FPR (%) | best recall at that FPR (%) | mean T_s (%) | AUC | "
        + " | ".join(kinds)
        + " |",
        "|---|---|---:|---:|---:|---:|---:|---:|" + "---:|" * len(kinds),
    ]
    for name, rows in found.items():
        for modality, row in rows.items():
            result = row.result
            cells = [
                f"{row.per_type[k][0]} / {row.per_type[k][1]}" if k in row.per_type else "—" for k in kinds
            ]
            lines.append(
                f"| {name} | {modality} | {result.threshold:.4f} | {pct(result.recall)} | {pct(result.fpr)} | "
                f"{pct(result.best_recall)} | {pct(result.ts_mean)} | {auc_cell(result.auc, None).split(' ')[0]} | "
                + " | ".join(cells)
                + " |"
            )
    return lines
