"""The evaluate job: one evaluation run, written as tables (.md, .json), a summary recording and an HTML report."""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

from rfr_viz.charts.report_html import REPORT_NAME, write_report
from rfr_viz.recordings.evaluation import record_evaluation
from rfr_viz.viewer.rrd import check_recording_file
from robofailring.atomic import output_lock, remove_file_leftovers
from robofailring.errors import SplitError
from robofailring.evaluation.folds_alone import FoldsAlone
from robofailring.evaluation.job import (
    EvaluateConfig,
    check_growth,
    cross_validate_alone,
    growth_curve,
    run_evaluation,
)
from robofailring.evaluation.result import EvaluationResult
from robofailring.evaluation.written import write_evaluation
from robofailring.outputs import check_output_folder, check_own_files


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
        """Inputs not read and test trajectories not scored (an unknown task, too short), all listed."""
        result = self.result
        return len(result.skipped_unknown_task) + len(result.skipped_too_short) + len(result.skipped_inputs)


@dataclass(frozen=True)
class FoldsOutcome:
    """`evaluate --folds` on data whose split gives no held-out evaluation: the cross-validation alone."""

    result: FoldsAlone
    json_path: Path
    markdown_path: Path
    report: Path


def evaluate(config: EvaluateConfig, *, growth: tuple[int, ...] = ()) -> EvaluateOutcome | FoldsOutcome:
    """Check the output folder, run the evaluation, and write its tables, recording and report,
    holding the output's lock and each output file's throughout (two runs into one folder never
    interleave; a `watch --save` into one of its files stops it before work).

    `growth` (labelled failures per task, e.g. 0, 1, 2, 4) adds the learning curve: one more
    evaluation per level, its memory under `<out>/growth-<n>/`. With `config.folds`, data whose split
    gives no held-out evaluation (`SplitError`) is still cross-validated: a `FoldsOutcome`, no recording."""
    out = Path(config.out)
    check_output_folder(
        out,
        inputs=[
            config.data.root,
            config.test_data.root if config.test_data else None,
            config.memory,
        ],
    )
    if growth:
        check_growth(config)
    files = [
        out / name for name in (f"{config.name}.json", f"{config.name}.md", f"{config.name}.rrd", REPORT_NAME)
    ]
    with ExitStack() as held:
        held.enter_context(output_lock(out))
        for file in files:  # a `watch --save` into one of them, or another job writing it: stop before work
            held.enter_context(output_lock(file))
        remove_file_leftovers(out)
        check_own_files(file for file in files if file.suffix != ".rrd")
        check_recording_file(out / f"{config.name}.rrd")
        try:
            result = run_evaluation(config)
        except SplitError as held_out:  # with --folds, the cross-validation needs no split
            return _folds_alone(cross_validate_alone(config, held_out), out)
        if growth:
            result.growth = growth_curve(config, growth, full=result)
        json_path, markdown_path = write_evaluation(result, out)
        recording = record_evaluation([result], out=out / f"{config.name}.rrd")
        report = write_report(
            [result.to_dict()],
            out / REPORT_NAME,
            markdown=[result.to_markdown()],
            recordings={"summary recording (charts and tables)": recording},
        )
    return EvaluateOutcome(
        result=result, json_path=json_path, markdown_path=markdown_path, recording=recording, report=report
    )


def _folds_alone(result: FoldsAlone, out: Path) -> FoldsOutcome:
    json_path, markdown_path = write_evaluation(result, out)
    report = write_report([result.to_dict()], out / REPORT_NAME, markdown=[result.to_markdown()])
    return FoldsOutcome(result=result, json_path=json_path, markdown_path=markdown_path, report=report)
