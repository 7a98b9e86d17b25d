"""Encoder comparison (paper Table 3): the same split under several encoders, each calibrated, side by side."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from robofailring.encoders import encoder_slug, load_encoder
from robofailring.evaluation import (
    CalibrateConfig,
    EvaluateConfig,
    EvaluationResult,
    build_training_memory,
    calibrate,
    run_evaluation,
)
from robofailring.metrics import rates, timeliness


@dataclass(frozen=True)
class CompareEncodersConfig:
    data: Path  # dataset with train/test splits (or a hash split)
    out: Path  # one memory per encoder is written under out/memory-<encoder>
    encoders: tuple[str, ...]  # two or more encoder specs
    target_fpr: float | None = 0.05  # calibrate each encoder's δ on training successes; None: paper δ
    test_data: Path | None = None
    test_split: str = "test"
    k: int = 5
    cache_dir: Path | None = None
    device: str | None = None


def compare_encoders(config: CompareEncodersConfig) -> list[EvaluationResult]:
    """Build, calibrate and evaluate one memory per encoder on the same split."""
    if len(config.encoders) < 2:
        raise ValueError("an encoder comparison needs at least two encoders")
    results = []
    for spec in config.encoders:
        slug = encoder_slug(load_encoder(spec, device=config.device).identity)
        memory_dir = Path(config.out) / f"memory-{slug}"
        base = EvaluateConfig(
            data=config.data,
            out=Path(config.out),
            encoder=spec,
            test_data=config.test_data,
            test_split=config.test_split,
            k=config.k,
            name=slug,
            cache_dir=config.cache_dir,
            device=config.device,
        )
        build_training_memory(replace(base, memory_out=memory_dir))
        if config.target_fpr is not None:
            calibrate(
                CalibrateConfig(
                    data=config.data,
                    memory=memory_dir,
                    target_fpr=config.target_fpr,
                    k=config.k,
                    cache_dir=config.cache_dir,
                    device=config.device,
                )
            )
        results.append(run_evaluation(replace(base, memory=memory_dir)))
    return results


def comparison_table(results: Sequence[EvaluationResult]) -> str:
    """Markdown: each encoder at its operating δ, with recall, FPR, T_s and per-frame latency."""
    lines = [
        "| encoder | δ | Recall (%) | FPR (%) | mean T_s (%) | latency per frame (ms) |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for result in results:
        delta = result.operating_delta
        at = rates(result.scored, delta)
        saving = timeliness(result.scored, delta).mean_saving
        lines.append(
            f"| `{result.encoder}` | {delta:.4f} | {_pct(at.recall)} | {_pct(at.fpr)} | {_pct(saving)} | "
            f"{result.latency_ms.get('total', float('nan')):.2f} |"
        )
    return "\n".join(lines)


def _pct(value: float) -> str:
    return "—" if math.isnan(value) else f"{100 * value:.2f}"
