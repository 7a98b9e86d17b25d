"""The memory entries behind an evaluation's false alarms, most culpable first: the candidates to prune, for
the JSON (`false_alarm_entries`) and the tables."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

from robofailring.detection.detector import DetectionTrace
from robofailring.evaluation.markdown import markdown_text
from robofailring.evaluation.metrics import ScoredTrajectory


def false_alarm_entries(
    false_alarms: Sequence[ScoredTrajectory], traces: Mapping[str, DetectionTrace], delta: float
) -> list[dict[str, Any]]:
    """Memory entries that were the top neighbour at a false alarm at `delta`, most culpable first."""
    blame: Counter[int] = Counter()
    for scored in false_alarms:
        trace = traces[scored.key].with_delta(delta)
        view, t_det = trace.detected_view, trace.t_det
        if view is not None and t_det is not None:
            for neighbor in trace.neighbors(view, t_det)[:1]:
                blame[neighbor.index] += 1
    memory = next(iter(traces.values())).memory if traces else None
    rows = []
    for index, count in blame.most_common():
        assert memory is not None
        entry = memory.entries[index]
        rows.append(
            {
                "index": index,
                "false_alarms": count,
                "task": entry.task,
                "symbol": entry.symbol,
                "episode": entry.episode,
                "view": entry.view,
                "moment": entry.moment,  # a dense memory's entries of one run differ only here
            }
        )
    return rows


def blame_markdown(blamed: Sequence[dict[str, Any]], *, shown: int = 10) -> list[str]:
    """The first `shown` entries behind the most false alarms, as a table (none: no lines)."""
    if not blamed:
        return []
    lines = [
        "",
        "Memory entries behind the most false alarms (candidates to prune):",
        "",
        "| entry | false alarms | task | symbol | episode | view | moment |",
        "|---:|---:|---|---|---|---|---|",
    ]
    for row in blamed[:shown]:
        lines.append(
            f"| {row['index']} | {row['false_alarms']} | {markdown_text(row['task'])} | "
            f"{markdown_text(row['symbol'], code=True)} | "
            + " | ".join(markdown_text(row[name]) for name in ("episode", "view", "moment"))
            + " |"
        )
    return lines
