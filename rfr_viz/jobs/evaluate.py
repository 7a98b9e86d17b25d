"""`evaluate` with its outputs: <name>.json, <name>.md, <name>.rrd and the browser report, under one lock."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rfr_viz.charts.report_html import REPORT_NAME, write_report
from rfr_viz.recordings.evaluation import record_evaluation
from robofailring.atomic import output_lock, remove_file_leftovers
from robofailring.evaluation.run import EvaluateConfig, EvaluationResult, run_evaluation, write_evaluation
from robofailring.outputs import check_output_folder


@dataclass(frozen=True)
class EvaluationOutputs:
    result: EvaluationResult
    json_path: Path
    md_path: Path
    recording: Path
    report: Path


def evaluate(config: EvaluateConfig) -> EvaluationOutputs:
    """Run the evaluation and write its files into `config.out`, holding the output's lock throughout."""
    out = Path(config.out)
    check_output_folder(out, inputs=[config.data, config.test_data, config.memory])
    with output_lock(out):
        remove_file_leftovers(out)
        result = run_evaluation(config)
        json_path, md_path = write_evaluation(result, out)
        recording = record_evaluation([result], out=out / f"{config.name}.rrd")
        report = write_report(
            [result.to_dict()],
            out / REPORT_NAME,
            markdown=[result.to_markdown()],
            recordings={"summary recording (charts and tables)": recording},
        )
    return EvaluationOutputs(result, json_path, md_path, recording, report)
