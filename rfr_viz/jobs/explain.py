"""The failure report read back from a recording or from `detect --json`, for `robofailring explain`."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from rfr_viz.viewer.rrd import recording_properties
from robofailring.errors import DataError, SettingError
from robofailring.explain.report import FailureReport
from robofailring.explain.vlm import VLMAnswer, VLMCallError, VLMConfig, ask_vlm
from robofailring.jsontext import parse_json


@dataclass(frozen=True)
class Explanation:
    """A VLM's answer about a failure report read back from a recording or `detect --json`."""

    report: FailureReport
    answer: VLMAnswer

    @property
    def failure(self) -> VLMCallError | None:
        """Why there is no answer: the VLM call failed."""
        return (
            None if self.answer.error is None else VLMCallError(f"the VLM call failed: {self.answer.error}")
        )

    def to_json(self) -> str:
        """`{model, answer, latency_s}`, or `{model, error}` when the call failed."""
        return json.dumps(self.answer.to_dict())

    def to_text(self) -> str:
        report, answer = self.report, self.answer
        return (
            f"{report.current_task}: failure at frame {report.t_det} in view {report.view} "
            f"(S_t = {report.similarity:.3f}); {answer.model} answered in {answer.latency_s:.1f} s:\n\n"
            f"{answer.answer}"
        )


def explain(source: Path, vlm: VLMConfig | None, *, data_root: Path | None = None) -> Explanation:
    """Ask `vlm` about the report in `source` (its images looked up under `data_root` when the data moved).

    Its images are sent only from under the folder the user named, `data_root` (without it, none is sent):
    the folders the file itself lists are never trusted, nor the one it lies in (a report may be shared or
    edited, and saved beside your own files)."""
    if vlm is None:
        raise SettingError("explain needs --vlm-url and --vlm-model")
    report = read_report(source)
    if data_root is not None:
        report = report.relocated(data_root)
    return Explanation(report=report, answer=ask_vlm(report, vlm))


def read_report(source: Path) -> FailureReport:
    """The report of a replay recording (`.rrd`, its `report` property) or of `detect --json` output, with
    no folder named for its images yet (`FailureReport.roots`: `explain` names `--data-root`).

    A file that holds no detection, or is neither, is a DataError naming it.
    """
    source = Path(source)
    if not source.is_file():
        raise DataError(f"no file at {source}")
    if source.suffix == ".rrd":
        try:
            found = recording_properties(source)
        except Exception as error:  # RrdReader raises its own types on a file that is not a recording
            raise DataError(f"{source} is not a readable Rerun recording ({error})") from error
        if "report" not in found:
            if found.get("t_det") == -1:
                raise DataError(
                    f"{source}: the detector never fired in this recording, so there is nothing to explain"
                )
            raise DataError(f"{source} has no failure report (a replay or review recording has one)")
        text = str(found["report"])
    else:
        text = source.read_text(encoding="utf-8", errors="replace")
    data = parse_json(text, source=f"{source} (a .rrd recording or `detect --json` output)")
    if isinstance(data, dict) and "report" in data and "t_det" in data and "current_task" not in data:
        if data["report"] is None:
            raise DataError(
                f"{source}: the detector never fired (t_det is null), so there is nothing to explain"
            )
        data = data["report"]
    if not isinstance(data, dict):
        raise DataError(f"{source} does not hold a failure report")
    return FailureReport.from_dict(data, source=str(source))
