"""`compare-encoders` with its outputs: the side-by-side table (comparison.md) and comparison recordings."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from rfr_viz.jobs.compare import CompareConfig, compare
from rfr_viz.jobs.recorded import Recordings
from robofailring.atomic import output_lock, remove_file_leftovers, write_text_atomic
from robofailring.detection.config import DetectorConfig
from robofailring.evaluation.result import EvaluationResult
from robofailring.jobs.compare_encoders import CompareEncodersConfig, compare_encoders, comparison_table
from robofailring.outputs import check_output_folder


@dataclass
class EncoderComparison:
    results: list[EvaluationResult]
    table: str  # markdown, also written to `table_path`
    table_path: Path
    recordings: list[Path] = field(default_factory=list)


def run_encoder_comparison(
    config: CompareEncodersConfig,
    *,
    recordings: int = 3,
    existing: Mapping[str, EvaluationResult] | None = None,
) -> EncoderComparison:
    """Evaluate every encoder on the same split, write `out/comparison.md` and replay the first failures;
    an encoder evaluated already on that split is given by its result in `existing` (by encoder spec)."""
    check_output_folder(config.out, inputs=[config.data.root])
    with output_lock(config.out):
        remove_file_leftovers(config.out)
        return _run_encoder_comparison(config, recordings=recordings, existing=existing)


def _run_encoder_comparison(
    config: CompareEncodersConfig, *, recordings: int, existing: Mapping[str, EvaluationResult] | None
) -> EncoderComparison:
    results = compare_encoders(config, existing=existing)
    table = comparison_table(results)
    table_path = Path(config.out) / "comparison.md"
    write_text_atomic(table_path, table + "\n", claim=True)
    keys = tuple(t.key for t in results[0].scored if t.is_failure)[: max(recordings, 0)]
    replayed = (
        compare(
            CompareConfig(
                data=config.test_data or config.data,
                detectors=tuple(
                    DetectorConfig(memory=Path(r.memory), scoring=config.scoring, placement=config.placement)
                    for r in results
                ),
                recordings=Recordings(out=Path(config.out) / "recordings", trajectories=keys),
            )
        ).recordings
        if keys
        else []
    )
    return EncoderComparison(results=results, table=table, table_path=table_path, recordings=replayed)
