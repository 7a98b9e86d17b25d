"""Command-line options and messages shared by several verbs (each option is declared once, here or, for the
options that make one value, in `robofailring.cli.option_groups`).

The verbs live in `robofailring.cli.verbs` (the library's) and `rfr_viz.cli.*` (those that record);
`rfr_viz.cli.app` assembles them into the one `robofailring` command (docs/architecture.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Final

import typer

from robofailring.data.model import Skipped
from robofailring.data.selection import DataSelection
from robofailring.errors import SettingError
from robofailring.memory.references import ReferenceCheck

StrideOption = Annotated[
    int,
    typer.Option(
        "--stride",
        help="Score every Nth frame of long episodes (I_0 stays frame 0; t_det and T_s in original frames).",
    ),
]


#: Lines of one list (inputs not read, trajectories skipped) printed before one line counts the rest.
SHOWN_LINES: Final[int] = 20


def report_skipped(skipped: Sequence[Skipped], *, kept_in: str | None = None) -> None:
    """One summary line of what the loaders did not read, then the first `SHOWN_LINES` with their reason
    (stderr); `kept_in`: the output listing them all, named in the line that counts the rest."""
    if not skipped:
        return
    typer.secho(
        f"note: {len(skipped):,} folder(s)/file(s) under the data were not read:",
        fg=typer.colors.YELLOW,
        err=True,
    )
    echo_first([f"  {item.path}: {item.reason}" for item in skipped], kept_in=kept_in, err=True)


def report_skipped_runs(skipped: Sequence[tuple[str, str]], *, kept_in: str | None = None) -> None:
    """The trajectories a verb skipped, `skipped <key>: <reason>`, the first `SHOWN_LINES` of them."""
    echo_first([f"skipped {key}: {reason}" for key, reason in skipped], kept_in=kept_in)


def echo_first(lines: Sequence[str], *, kept_in: str | None = None, err: bool = False) -> None:
    """The first `SHOWN_LINES` of `lines`, then one line counting the rest (10,000 skipped episodes are not
    10,000 lines), naming `kept_in`, where they are all, when there is such an output."""
    for line in lines[:SHOWN_LINES]:
        typer.echo(line, err=err)
    if len(lines) > SHOWN_LINES:
        where = f" (all in {kept_in})" if kept_in else ""
        typer.echo(f"  … and {len(lines) - SHOWN_LINES:,} more{where}", err=err)


def print_notes(notes: Sequence[str]) -> None:
    """Warnings and notes a job returned, one line each on stderr."""
    for note in notes:
        typer.secho(note, fg=typer.colors.YELLOW, err=True)


def warn_missing_references(memory: Path, check: ReferenceCheck | None) -> None:
    """One warning line when a memory's reference images cannot be found (nothing silent)."""
    if check is not None and not check.ok:
        typer.secho(
            f"warning: memory {memory}: "
            + check.summary(
                hint="; if the dataset moved, pass --data-root DIR (see `robofailring memory-info`)"
            ),
            fg=typer.colors.YELLOW,
            err=True,
        )


LeaveOneOutOption = Annotated[
    bool, typer.Option("--leave-one-out", help="Hide each trajectory's own episode from the memory.")
]
FpsOption = Annotated[
    float | None,
    typer.Option(
        "--fps", help="Frame rate of the `time` timeline, 0.001–10000.", show_default="the data's, else 10"
    ),
]
WorkersOption = Annotated[int, typer.Option("--workers", help="Simulation processes.")]
RandomizeOption = Annotated[
    int,
    typer.Option(
        "--randomize",
        help="The trained encoder also trains on N simulated episodes of the data's tasks under random looks "
        "(object, table, tray and goal colours, light, camera shifts, object size) at the data's image size "
        "and frames, spread over every failure family and success; simulated once and cached (0: none).",
    ),
]


def tested_on(data: DataSelection, root: Path | None, labels: Path | None) -> DataSelection | None:
    """The dataset `--test-data` names, read as DATA is, with its own labels (`--test-labels`; default: DATA's
    `--labels`); None without --test-data."""
    if root is None:
        if labels is not None:
            raise SettingError("--test-labels labels the dataset of --test-data: give --test-data too")
        return None
    return data.other(root, labels=labels)
