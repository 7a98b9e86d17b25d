"""The evaluate job: one evaluation run, written as tables (.md, .json), a summary recording and an HTML report."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rfr_viz.charts.report_html import REPORT_NAME, write_report
from rfr_viz.recordings.evaluation import record_evaluation
from robofailring.evaluation.run import EvaluateConfig, EvaluationResult, run_evaluation, write_evaluation
from robofailring.outputs import check_output_folder


@dataclass(frozen=True)
class EvaluateOutcome:
    """An evaluation and the files it was written to."""

    result: EvaluationResult
    json_path: Path
    markdown_path: Path
    recording: Path  # the summary recording (charts and tables)
    report: Path  # the HTML report for a browser

    @property
    def skipped(self) -> int:
        """Test trajectories not scored (an unknown task, too short); listed in the table."""
        return len(self.result.skipped_unknown_task) + len(self.result.skipped_too_short)


def evaluate(config: EvaluateConfig) -> EvaluateOutcome:
    """Check the output folder, run the evaluation, and write its tables, recording and report."""
    check_output_folder(config.out, inputs=[config.data, config.test_data, config.memory])
    result = run_evaluation(config)
    json_path, markdown_path = write_evaluation(result, config.out)
    recording = record_evaluation([result], out=Path(config.out) / f"{config.name}.rrd")
    report = write_report(
        [result.to_dict()],
        Path(config.out) / REPORT_NAME,
        markdown=[result.to_markdown()],
        recordings={"summary recording (charts and tables)": recording},
    )
    return EvaluateOutcome(
        result=result, json_path=json_path, markdown_path=markdown_path, recording=recording, report=report
    )
