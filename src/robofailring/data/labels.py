"""A labels file: outcome and failure symbol per episode, for data whose names do not say them.

A JSON list of objects or a CSV file with a header, one row per episode:
`episode_index` (a LeRobot episode) or `episode` (an episode folder's name), `outcome`
(`success` or `failure`), `symbol` (the failure symbol, e.g. `grasp_wp2`, or one of the
dataset's vocabulary; empty for a success, and for a failure whose type was not labelled: it gets
the symbol `failure`) and an optional `description` (free text: that failure's grounded sentence).
An optional `task` column names the episode's task (it wins over `--task` and the data's own), and
an optional `onset_frame` a failure's first frame of the fault (an integer from 0, below the
episode's length; it wins over the data's own, e.g. the simulator's manifest), and an optional
`split` column the episode's split (`train`, `test`, `ood`, …; it wins over the data's own: once
one episode has a split, the dataset is not hash-split, and an episode without one is in none).
A row whose outcome is empty but whose task is given gives that episode its task and nothing else:
the run stays unlabelled (or as its data labels it); a file of only `episode,task` columns (unlabelled
rollouts of several tasks, for `triage`) is such rows alone, but a file whose `outcome` column is empty
throughout labels nothing and is refused. Other columns (e.g. those `review --write-labels` adds) are
ignored. A CSV saved by Excel as
"CSV UTF-8" (a byte-order mark before the header) reads like any other.

A tool that writes a labels file where one already is (`review --write-labels`) merges into it
(`merge_label_rows`): what a person filled in is never blanked, and a file that is not a labels
file is never written over.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path

from robofailring.data.grounding import UNTYPED, Vocabulary, parse_symbol
from robofailring.data.model import Outcome, Skipped, Trajectory, parse_onset_frame
from robofailring.errors import DataError, OutputError, SymbolError
from robofailring.jsontext import parse_json

#: The columns a person fills in: kept from an existing labels file whenever they are not empty.
FILLED_COLUMNS: tuple[str, ...] = ("outcome", "symbol", "description", "task", "onset_frame", "split")
#: Every column this module reads (a header names them in any case, with spaces around).
LABEL_COLUMNS: tuple[str, ...] = ("episode_index", "episode", *FILLED_COLUMNS)


@dataclass(frozen=True)
class Label:
    episode: str  # `episode_<index>` for LeRobot, else the episode folder's name
    outcome: Outcome | None  # None: the row says the episode's task alone (an unlabelled run)
    symbol: str | None
    task: str | None = None  # the episode's task, when the labels file says it
    description: str | None = None  # the failure in the labeller's own words
    # where the failure starts (checked against the episode's length when applied)
    onset_frame: int | None = None
    split: str | None = None  # the episode's split, when the labels file says it
    row: int | None = None  # the row of the labels file it was read from (for errors naming it)


def read_labels(path: Path, *, vocabulary: Vocabulary | None = None) -> dict[str, Label]:
    """Labels by episode; every bad row is an error naming the file, the row and the value.

    Symbols are checked against Table 5 and `vocabulary` (a dataset's own symbols).
    """
    path = Path(path)
    rows = _rows(path)
    labels: dict[str, Label] = {}
    for number, row in enumerate(rows, 1):
        if not str(row.get("outcome") or "").strip() and not str(row.get("task") or "").strip():
            continue  # a row not labelled yet (`review --write-labels` leaves outcome empty): counted by `unlabelled_rows`
        label = replace(_label(row, where=f"{path} row {number}", vocabulary=vocabulary), row=number)
        if label.episode in labels:
            raise DataError(f"{path} row {number}: episode {label.episode!r} is labelled twice")
        labels[label.episode] = label
    outcomes = any(label.outcome is not None for label in labels.values())
    if not outcomes and (not labels or any("outcome" in row for row in rows)):  # an outcome column, all empty
        raise DataError(
            f"labels file {path} holds no labelled row (columns: episode_index or episode, outcome, symbol, "
            "description, task; fill in `outcome`, or `task` alone for unlabelled runs of several tasks)"
        )
    return labels


def unlabelled_rows(path: Path) -> Skipped | None:
    """What a labels file left unlabelled (rows of its `outcome` column left empty), as a Skipped to report,
    or None; a file without an outcome column (`episode,task`: tasks of unlabelled runs) leaves nothing."""
    blank = [row for row in _rows(Path(path)) if "outcome" in row and not str(row["outcome"] or "").strip()]
    if not blank:
        return None
    tasks = sum(bool(str(row.get("task") or "").strip()) for row in blank)
    told = f" (the task of {tasks} of them was)" if tasks else ""
    return Skipped(
        path=Path(path),
        reason=f"{len(blank)} row(s) with an empty outcome (not labelled yet) were not applied{told}",
    )


def _rows(path: Path) -> list[dict[str, object]]:
    """The rows of a labels file (JSON list of objects, else CSV with a header)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # Excel's "CSV UTF-8" starts with a byte-order mark
    except (OSError, UnicodeDecodeError) as error:
        raise DataError(f"cannot read labels file {path}: {error}") from error
    if path.suffix.lower() != ".json":
        return _read_csv(text, path)[1]
    loaded = parse_json(text, source=f"labels file {path}")
    if not isinstance(loaded, list) or not all(isinstance(row, dict) for row in loaded):
        raise DataError(
            f"labels file {path} must hold a JSON list of objects (episode_index, outcome, symbol)"
        )
    return [_renamed(row, _column_names(row, path)) for row in loaded]


def _read_csv(text: str, path: Path) -> tuple[list[str], list[dict[str, object]]]:
    """A labels CSV's header and rows, its labels columns under the names this module reads; DataError
    when it does not parse (a quote never closed) or names a column twice."""
    reader = csv.DictReader(io.StringIO(text, newline=""), strict=True)  # a quoted cell may hold a line break
    try:
        rows = [dict(row) for row in reader]
    except csv.Error as error:  # e.g. a quote never closed: the rest of the file would be one cell
        raise DataError(f"labels file {path} line {reader.line_num}: not a readable CSV ({error})") from error
    header = list(reader.fieldnames or [])
    names = _column_names(header, path)  # a column named twice, even where no row follows
    return [names.get(name, name) for name in header], [_renamed(row, names) for row in rows]


def _renamed(row: dict[str, object], names: dict[str, str]) -> dict[str, object]:
    """The row with the labels columns under the names this module reads (`names`: `_column_names`)."""
    return {names.get(name, name): value for name, value in row.items()}


def _column_names(names: Iterable[object], path: Path) -> dict[str, str]:
    """The labels columns among `names`, as this module reads them (`Outcome`, ` outcome ` -> `outcome`);
    a column named twice that way is an error, never one of the two picked silently."""
    found: dict[str, str] = {}
    for name in names:
        known = str(name).strip().lower()
        if known not in LABEL_COLUMNS:
            continue
        if known in found.values():
            first = next(given for given, column in found.items() if column == known)
            raise DataError(
                f"labels file {path}: columns {first!r} and {name!r} both name {known!r}; keep one"
            )
        found[str(name)] = known
    return found


def _row_key(row: dict[str, object]) -> str | None:
    """The episode a labels row names (`episode_<index>` or the episode's name), None when none."""
    index, name = str(row.get("episode_index") or "").strip(), str(row.get("episode") or "").strip()
    return f"episode_{index}" if index else (name or None)


def merge_label_rows(
    path: Path, rows: list[dict[str, str]], columns: Iterable[str]
) -> tuple[list[str], list[dict[str, str]]]:
    """The columns and rows to write to the labels CSV at `path`: `rows` merged into what is there.

    No file at `path`: `rows` as they are. A labels CSV there (a header with `episode` or
    `episode_index` and `outcome`): its rows are all kept, in their order and with their own extra
    columns; a row for the same episode takes the new values of the tool's columns, but a column
    the tool does not write keeps its value, and one a person fills in (`FILLED_COLUMNS`) keeps it
    when it is not empty; new episodes follow. Anything else at `path` (another CSV, a JSON
    labels file, a file that is not text) is refused with OutputError before anything is written.
    """
    path = Path(path)
    columns = list(columns)
    if not path.exists():
        return columns, rows
    refused = f"{path} exists and is not a labels CSV"
    if path.suffix.lower() == ".json":
        raise OutputError(f"{refused} (a JSON labels file is not rewritten): name a .csv file")
    try:
        header, table = _read_csv(path.read_text(encoding="utf-8-sig"), path)  # as read_labels reads it
    except (OSError, UnicodeDecodeError, DataError) as error:
        raise OutputError(f"{refused} ({error}); refusing to write over it") from error
    existing = [
        {name: value if isinstance(value, str) else "" for name, value in row.items() if name is not None}
        for row in table
    ]
    if "outcome" not in header or not {"episode", "episode_index"} & set(header):
        raise OutputError(
            f"{refused} (its header has no episode/episode_index and outcome columns); "
            "refusing to write over it: name a new file"
        )
    fresh = {_row_key(dict(row)): row for row in rows}
    merged: list[dict[str, str]] = []
    for kept in existing:
        new = fresh.pop(_row_key(dict(kept)), None)
        if new is not None:
            kept = new | {  # the tool's own columns refreshed; a person's never blanked
                name: value
                for name, value in kept.items()
                if name not in columns or (name in FILLED_COLUMNS and value.strip())
            }
        merged.append(kept)
    merged.extend(fresh.values())
    return columns + [name for name in header if name not in columns], merged


def _label(row: dict[str, object], *, where: str, vocabulary: Vocabulary | None) -> Label:
    index, name = row.get("episode_index"), row.get("episode")
    if index not in (None, ""):
        try:
            episode = f"episode_{int(str(index))}"
        except ValueError as error:
            raise DataError(f"{where}: episode_index {index!r} is not an integer") from error
    elif name not in (None, ""):
        episode = str(name)
    else:
        raise DataError(f"{where}: no episode_index (or episode) column")
    task = str(row.get("task") or "").strip() or None
    if not str(row.get("outcome") or "").strip():  # the task alone (read_labels passes no row without one)
        return Label(episode=episode, outcome=None, symbol=None, task=task, split=_split(row))
    try:
        outcome = Outcome(str(row.get("outcome", "")).strip().lower())
    except ValueError as error:
        raise DataError(f"{where}: outcome {row.get('outcome')!r} is not 'success' or 'failure'") from error
    symbol = str(row.get("symbol") or "").strip() or None
    if symbol is not None:
        try:
            parse_symbol(symbol, vocabulary)
        except SymbolError as error:
            raise DataError(f"{where}: {error}") from error
    description = " ".join(str(row.get("description") or "").split()) or None
    split = _split(row)
    onset = parse_onset_frame(row.get("onset_frame"), length=None, where=where)
    if outcome is not Outcome.FAILURE:
        if onset is not None:
            raise DataError(
                f"{where}: onset_frame {row.get('onset_frame')!r} given for a success (only failures start)"
            )
        return Label(episode=episode, outcome=outcome, symbol=None, task=task, split=split)
    return Label(
        episode=episode,
        outcome=outcome,
        symbol=symbol or UNTYPED,
        description=description,
        task=task,
        onset_frame=onset,
        split=split,
    )


def _split(row: dict[str, object]) -> str | None:
    return str(row.get("split") or "").strip() or None


def label_key(trajectory: Trajectory, labels: dict[str, Label]) -> str | None:
    """The key of `labels` that labels `trajectory` (its episode, or its folder's name), None when none does."""
    for key in (trajectory.episode, trajectory.episode.rsplit("/", 1)[-1]):
        if key in labels:
            return key
    return None


def _onset(trajectory: Trajectory, label: Label, source: Path) -> int | None:
    """The labelled onset, checked against the episode's length; else the data's own for a failure."""
    if label.outcome is not Outcome.FAILURE:
        return None
    if label.onset_frame is None:
        return trajectory.onset_frame
    where = f"{source} row {label.row} (episode {label.episode})"
    return parse_onset_frame(label.onset_frame, length=trajectory.length, where=where)


def apply_labels(
    trajectories: Iterable[Trajectory], labels: dict[str, Label], *, source: Path
) -> list[Trajectory]:
    """The trajectories with their labelled outcome and symbol; a label for a missing episode is an error,
    and so is one naming by its last part (`demo_0`) episodes of several folders or files."""
    labelled = []
    found: set[str] = set()
    by_last_part: dict[str, list[str]] = {}
    for trajectory in trajectories:
        key = label_key(trajectory, labels)
        label = labels.get(key) if key is not None else None
        if key is not None and label is not None:
            found.add(key)
            if key != trajectory.episode:
                by_last_part.setdefault(key, []).append(trajectory.episode)
            trajectory = replace(
                trajectory,
                task=label.task or trajectory.task,
                split=label.split or trajectory.split,
            )
            if label.outcome is not None:  # else the row told the task alone: the run stays as its data says
                trajectory = replace(
                    trajectory,
                    outcome=label.outcome,
                    symbol=label.symbol,
                    description=label.description,
                    onset_frame=_onset(trajectory, label, source),
                )
        labelled.append(trajectory)
    for key, episodes in by_last_part.items():
        if len(episodes) > 1:
            raise DataError(
                f"labels file {source} row {labels[key].row}: episode {key!r} names {len(episodes)} episodes "
                f"({', '.join(episodes[:3])}{' …' if len(episodes) > 3 else ''}); name one by its whole key"
            )
    missing = [episode for episode in labels if episode not in found]
    if missing:
        known = ", ".join(t.episode for t in labelled[:5]) + (" …" if len(labelled) > 5 else "")
        raise DataError(
            f"labels file {source} names episode {missing[0]!r}, which is not in the dataset"
            + (f" ({len(missing)} such episodes)" if len(missing) > 1 else "")
            + f"; its episodes are: {known or 'none'}"
        )
    return labelled
