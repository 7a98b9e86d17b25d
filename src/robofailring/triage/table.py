"""`triage.csv`: the ranking as a labels file to fill, in the one format `--labels` reads.

The rows are in rank order: what triage found (score, frame, view, the nearest failure's symbol as
`suggested_symbol`, the nearest normal frame, the command that opens the episode at its peak) and
empty `outcome`, `symbol` and `description` columns for a person to fill; `build-memory --labels
triage.csv --add-to MEMORY` and `evaluate --labels triage.csv` read it back (rows still without
an outcome are reported as not applied). Written into an existing file, the rows are merged
(`robofailring.data.labels.merge_label_rows`): what a person filled in is kept, never blanked.
"""

from __future__ import annotations

import csv
import io
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Final

import numpy as np

from robofailring.atomic import write_text_atomic
from robofailring.data.labels import merge_label_rows
from robofailring.data.model import Outcome, Trajectory
from robofailring.errors import DataError
from robofailring.triage.scoring import EpisodeScore

TRIAGE_NAME: Final[str] = "triage.csv"
COLUMNS: Final[tuple[str, ...]] = (
    "rank",
    "episode",
    "task",
    "score",
    "peak",
    "frame",
    "view",
    "reference",
    "rule",
    "suggested_symbol",
    "suggested_description",
    "nearest_normal",
    "open",
    "outcome",
    "symbol",
    "description",
)


def check_table(path: Path) -> None:
    """Refuse, before any work, a file at `path` that is not a labels CSV (nothing is written over it)."""
    merge_label_rows(path, [], COLUMNS)


def check_unique_episodes(trajectories: Sequence[Trajectory]) -> None:
    """A labels file names an episode by its name alone: two tasks' episodes of one name would share a row."""
    repeated = [name for name, count in Counter(t.episode for t in trajectories).items() if count > 1]
    if repeated:
        raise DataError(
            f"episode name {repeated[0]!r} is used by {len(repeated)} episode(s) of several tasks; a labels "
            "file names episodes by name alone: triage one task at a time (--task)"
        )


def table_rows(
    ranked: Sequence[EpisodeScore],
    *,
    labelled: Mapping[str, Trajectory] = {},
    open_commands: Mapping[str, str] = {},
) -> list[dict[str, str]]:
    """One row per episode in rank order; an episode `labelled` (by `--labels`) has its label filled in."""
    rows = []
    for score in ranked:
        known = labelled.get(score.key)
        outcome = known.outcome if known is not None else None
        rows.append(
            {
                "rank": str(score.rank),
                "episode": score.episode,
                "task": score.task,
                "score": _number(score.rank_score),
                "peak": _number(score.peak),
                "frame": str(score.frame) if score.scored else "",
                "view": score.view,
                "reference": score.mode,
                "rule": score.rule,
                "suggested_symbol": score.failure_symbol,
                "suggested_description": score.failure_description,
                "nearest_normal": f"{score.normal_episode} frame {score.normal_frame}"
                if score.normal_episode
                else "",
                "open": open_commands.get(score.key, ""),
                "outcome": outcome.value if outcome is not None else "",
                "symbol": (known.symbol or "") if known is not None and outcome is Outcome.FAILURE else "",
                "description": (known.description or "") if known is not None else "",
            }
        )
    return rows


def write_table(path: Path, rows: Sequence[dict[str, str]]) -> Path:
    """Write the rows at `path` atomically, merged into a labels CSV already there, in rank order
    (rows of episodes this triage did not see keep their place after them)."""
    columns, merged = merge_label_rows(path, list(rows), COLUMNS)
    ranked = {row["episode"] for row in rows}
    order = sorted(
        range(len(merged)),
        key=lambda i: (
            merged[i].get("episode") not in ranked,
            _rank(merged[i]) if merged[i].get("episode") in ranked else i,
        ),
    )
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    writer.writerows(merged[i] for i in order)
    write_text_atomic(path, buffer.getvalue(), claim=True)
    return path


def _rank(row: Mapping[str, str]) -> int:
    try:
        return int(row.get("rank") or 0)
    except ValueError:
        return 0


def _number(value: float) -> str:
    return f"{value:.6f}" if np.isfinite(value) else ""
