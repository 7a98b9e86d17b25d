"""The compare-encoders job (paper Table 3), its config and its run: the same split under several encoders, each
calibrated, side by side.

Where the data has the robot's signals, the rows that compare the encoders are the cameras alone, each encoder with
its own calibrated thresholds: fused, the signals' thresholds would decide every encoder's row alike. The fused
row stands beside them (`evaluation.modalities`)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from robofailring.calibration.job import CalibrateConfig, calibrate
from robofailring.calibration.policy import DEFAULT_POLICY, ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_SCORING, Scoring
from robofailring.encoders import EncoderSpec, cache_identity
from robofailring.encoders.placement import DEFAULT_PLACEMENT, EncoderPlacement
from robofailring.errors import SettingError
from robofailring.evaluation.job import EvaluateConfig, build_training_memory, run_evaluation
from robofailring.evaluation.markdown import markdown_text
from robofailring.evaluation.result import EvaluationResult
from robofailring.memory.recipe import DEFAULT_RECIPE, MemoryRecipe
from robofailring.memory.signals.modality import BOTH, CAMERAS, SIGNALS_VIEW
from robofailring.outputs import unique_names


@dataclass(frozen=True)
class CompareEncodersConfig:
    data: DataSelection  # dataset with train/test splits (or a hash split), how it is read
    out: Path  # one memory per encoder is written under out/memory-<encoder>
    encoders: tuple[str, ...]  # two or more encoder specs
    # each encoder's thresholds calibrated on training successes; None: each rule's default (the paper's δ)
    threshold_policy: ThresholdPolicy | None = DEFAULT_POLICY
    test_data: DataSelection | None = None  # a second dataset to test on
    test_split: str = "test"
    recipe: MemoryRecipe = DEFAULT_RECIPE  # each encoder's memory: this recipe with its own encoder
    scoring: Scoring = DEFAULT_SCORING  # K and modality of every calibration and evaluation
    placement: EncoderPlacement = DEFAULT_PLACEMENT  # device, runtime, cache and Ray cluster of every encoder


def compare_encoders(
    config: CompareEncodersConfig, *, existing: Mapping[str, EvaluationResult] | None = None
) -> list[EvaluationResult]:
    """Build, calibrate and evaluate one memory per encoder on the same split; an encoder whose result is
    in `existing` (by encoder spec, e.g. the demo's headline evaluation of the same split) is taken as it is,
    unless its runs had signals and it lacks its cameras' own rows (judged on stored thresholds)."""
    if len(config.encoders) < 2:
        raise SettingError(
            f"an encoder comparison needs at least two encoders (--encoder A --encoder B), got {len(config.encoders)}"
        )
    given = Counter(EncoderSpec.parse(spec) for spec in config.encoders)
    twice = [str(spec) for spec, times in given.items() if times > 1]
    if twice:
        raise SettingError(f"--encoder {twice[0]} is given twice: each encoder is compared once")
    existing = existing or {}
    results = []
    slugs: list[str] = []
    for spec in config.encoders:
        if spec in existing and _gives_cameras(existing[spec]):
            results.append(existing[spec])
            continue
        opened = config.placement.open(spec).encoder
        slugs.append(EncoderSpec.slug(cache_identity(opened)))  # the same model in two runtimes: two slugs
        slug = unique_names(slugs)[-1]  # one model with two checkpoints: one slug, two folders (`…-2`)
        memory_dir = Path(config.out) / f"memory-{slug}"
        base = EvaluateConfig(
            data=config.data,
            out=Path(config.out),
            recipe=replace(config.recipe, encoder=spec),
            scoring=config.scoring,
            placement=config.placement,
            test_data=config.test_data,
            test_split=config.test_split,
            name=slug,
        )
        _, built = build_training_memory(replace(base, memory_out=memory_dir))
        if config.threshold_policy is not None:
            calibrate(
                CalibrateConfig(
                    data=config.data,
                    memory=memory_dir,
                    scoring=config.scoring,
                    placement=config.placement,
                    threshold_policy=config.threshold_policy,
                )
            )
        # thresholds: calibrated as `calibrate` just stored them, here with each modality's own beside them
        evaluated = replace(base, memory=memory_dir, threshold_policy=config.threshold_policy)
        result = run_evaluation(evaluated)  # what its memory's build did not use, listed with the rest
        results.append(replace(result, skipped_inputs=list(dict.fromkeys([*result.skipped_inputs, *built]))))
    return results


def _gives_cameras(result: EvaluationResult) -> bool:
    """Whether `result` has its cameras' own rows where its runs had signals (one judged on stored thresholds
    has none: its fused rows alone would not compare the encoders)."""
    signals = any(SIGNALS_VIEW in trace.scored_views for trace in result.traces.values())
    return bool(result.modalities) or not signals


def comparison_table(results: Sequence[EvaluationResult]) -> str:
    """Markdown: each encoder under each scoring rule at its threshold: recall, FPR, the best recall any
    threshold reaches at that FPR, T_s, AUC, latency, and the failure memory it used (`end` or `dense`); with the
    robot's signals, the cameras alone (each encoder's own thresholds) and the fused row beside."""
    lines = [
        "| encoder | failure memory | rule | modality | threshold | Recall (%) | FPR (%) | best recall at that FPR (%) "
        "| mean T_s (%) | AUC | latency per frame (ms) |",
        "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for result in results:
        latency = f"{result.latency_ms.get('total', float('nan')):.2f}"
        for rule in result.rules.values():
            by_modality = result.modalities.get(rule.rule.name, {})
            shown = (
                [
                    (modality, by_modality[modality].result)
                    for modality in (CAMERAS, BOTH)
                    if modality in by_modality
                ]
                if by_modality
                else [(BOTH if result.modalities else "all", rule)]
            )
            for modality, found in shown:
                lines.append(
                    f"| {markdown_text(result.encoder, code=True)} | {result.failure_frames}, {result.pairing} | "
                    f"{rule.rule.name} | {modality} | {rule.rule.symbol} = {found.threshold:.4f} | "
                    f"{_pct(found.recall)} | {_pct(found.fpr)} | {_pct(found.best_recall)} | {_pct(found.ts_mean)} | "
                    f"{found.auc:.3f} | {latency} |"
                )
    return "\n".join(lines)


def _pct(value: float) -> str:
    return "—" if math.isnan(value) else f"{100 * value:.2f}"
