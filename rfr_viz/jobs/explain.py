"""The failure report read back from a recording or from `detect --json`, for `robofailring explain`."""

from __future__ import annotations

import json
from pathlib import Path

from rfr_viz.viewer.control import recording_properties
from robofailring.errors import DataError
from robofailring.explain.report import FailureReport


def read_report(source: Path) -> FailureReport:
    """The report of a replay recording (`.rrd`, its `report` property) or of `detect --json` output.

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
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise DataError(
            f"{source} is neither a .rrd recording nor `detect --json` output ({error})"
        ) from error
    if isinstance(data, dict) and "report" in data and "t_det" in data and "current_task" not in data:
        if data["report"] is None:
            raise DataError(
                f"{source}: the detector never fired (t_det is null), so there is nothing to explain"
            )
        data = data["report"]
    if not isinstance(data, dict):
        raise DataError(f"{source} does not hold a failure report")
    return FailureReport.from_dict(data, source=str(source))
