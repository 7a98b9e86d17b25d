"""The rollout summary: per episode the alarm, its frame and the env's outcome, and the alarms against the env's
own success as a table (the monitor's recall and false-alarm rate on those rollouts), written as `evaluate`
writes its own: `rollouts.json` and `rollouts.md`, atomically."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Final

from robofailring.atomic import write_text_atomic
from robofailring.evaluation.markdown import markdown_text
from robofailring.evaluation.metrics import ConfusionRates, json_number

SUMMARY_NAME: Final[str] = "rollouts"  # rollouts.json and rollouts.md


@dataclass(frozen=True)
class RolloutRow:
    """One saved episode: where it fired first, how it ended, and the env's outcome (None: none given)."""

    episode: str
    task: str
    frames: int
    alarm_frame: int | None
    ended: str
    outcome: str | None
    stopped: str | None = None


@dataclass(frozen=True)
class RolloutSummary(ConfusionRates):
    """Alarms against the env's outcome: a failure with an alarm is caught (tp), a success with one a false
    alarm (fp); episodes whose outcome is unknown (the env gave none, or the monitor cut them) are counted apart."""

    rows: tuple[RolloutRow, ...]
    tp: int
    fn: int
    fp: int
    tn: int
    unknown: int  # episodes without an outcome
    unknown_alarms: int  # of them, those with an alarm
    uncalibrated: tuple[
        str, ...
    ] = ()  # a sentence per rule judged at its default threshold (no FPR promised)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": SUMMARY_NAME,
            "episodes": len(self.rows),
            "confusion": {"tp": self.tp, "fn": self.fn, "fp": self.fp, "tn": self.tn},
            "recall": json_number(self.recall),
            "false_alarm_rate": json_number(self.fpr),
            "unknown_outcome": {"episodes": self.unknown, "alarms": self.unknown_alarms},
            "uncalibrated_rules": list(self.uncalibrated),
            "rows": [asdict(row) for row in self.rows],
        }

    def to_markdown(self) -> str:
        def rate(value: float) -> str:
            return "—" if value != value else f"{100 * value:.1f} %"

        lines = [
            f"## Rollouts — {len(self.rows)} episode(s) under the monitor",
            "",
            "| | env: failure | env: success |",
            "|---|---|---|",
            f"| alarm | {self.tp} | {self.fp} |",
            f"| no alarm | {self.fn} | {self.tn} |",
            "",
            f"Recall {rate(self.recall)} ({self.tp}/{self.tp + self.fn} failures caught), false-alarm rate "
            f"{rate(self.fpr)} ({self.fp}/{self.fp + self.tn} successes); {self.unknown} episode(s) without an "
            f"outcome ({self.unknown_alarms} with an alarm) are not in the table.",
            *(f"\n**Uncalibrated:** {markdown_text(note)}." for note in self.uncalibrated),
            "",
            "| episode | task | frames | first alarm | ended | outcome |",
            "|---|---|---|---|---|---|",
        ]
        for row in self.rows:
            alarm = "—" if row.alarm_frame is None else str(row.alarm_frame)
            ended = row.ended if row.stopped is None else f"{row.ended}: {row.stopped}"
            lines.append(
                f"| {markdown_text(row.episode)} | {markdown_text(row.task)} | {row.frames} | {alarm} | "
                f"{markdown_text(ended)} | {row.outcome or 'unknown'} |"
            )
        return "\n".join(lines)


def summarize(records: Sequence[dict[str, Any]], *, uncalibrated: Sequence[str] = ()) -> RolloutSummary:
    """The summary of saved rollouts' manifest records (`RolloutStore.records`, `read_rollouts`); `uncalibrated`:
    the detector's notes on rules judged at their default threshold (`FailureDetector.uncalibrated`)."""
    rows = tuple(
        RolloutRow(
            episode=str(record["episode"]),
            task=str(record["task"]),
            frames=int(record["frames"]),
            alarm_frame=record["monitor"]["alarm_frame"],
            ended=str(record["monitor"]["ended"]),
            outcome=record["outcome"],
            stopped=record["monitor"].get("stopped"),
        )
        for record in records
    )

    def count(outcome: str | None, alarm: bool) -> int:
        return sum(row.outcome == outcome and (row.alarm_frame is not None) == alarm for row in rows)

    return RolloutSummary(
        rows=rows,
        tp=count("failure", True),
        fn=count("failure", False),
        fp=count("success", True),
        tn=count("success", False),
        unknown=count(None, True) + count(None, False),
        unknown_alarms=count(None, True),
        uncalibrated=tuple(uncalibrated),
    )


def write_summary(summary: RolloutSummary, out: Path) -> tuple[Path, Path]:
    """`rollouts.json` and `rollouts.md` under `out`, written atomically."""
    json_path, md_path = Path(out) / f"{SUMMARY_NAME}.json", Path(out) / f"{SUMMARY_NAME}.md"
    write_text_atomic(json_path, json.dumps(summary.to_dict(), indent=2), claim=True)
    write_text_atomic(md_path, summary.to_markdown() + "\n", claim=True)
    return json_path, md_path
