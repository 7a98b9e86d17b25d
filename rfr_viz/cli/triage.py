"""The `triage` verb: rank the episodes of a dataset nobody labelled (docs/triage.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rfr_viz.cli.options import CameraCodecOption
from rfr_viz.codecs import CameraCodec
from robofailring.cli.exit_codes import finish
from robofailring.cli.groups import Declared, takes
from robofailring.cli.option_groups import DATA, DETECTOR, RULE_THRESHOLDS
from robofailring.cli.options import print_notes, report_skipped
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.memory.recipe import DEFAULT_ENCODER

app = typer.Typer(add_completion=False)  # composed into the one `robofailring` command by rfr_viz.cli.app


@app.command("triage")
@takes(
    data=DATA.without("vocabulary"),
    detector=DETECTOR.without(*RULE_THRESHOLDS, "modality").but(
        memory=Declared(
            Annotated[
                Path | None,
                typer.Option("--memory", help="Judge by this memory, its rules as calibrated (its encoder)."),
            ],
            None,
        ),
        encoder=Declared(
            Annotated[
                str | None,
                typer.Option(
                    "--encoder",
                    help="Encoder spec: the reference's without --memory, else the memory's.",
                    show_default=f"{DEFAULT_ENCODER} without --memory, else the memory's",
                ),
            ],
            None,
        ),
    ),
)
def triage_cmd(
    data: DataSelection,
    *,
    out: Annotated[
        Path, typer.Option("--out", help="Folder for triage.csv, triage.rrd, triage.html and replays/.")
    ],
    known_good: Annotated[
        Path | None,
        typer.Option(
            "--successes",
            help="A dataset of known-good runs (any layout; every episode a success): a success memory of "
            "them judges their tasks.",
        ),
    ] = None,
    replays: Annotated[
        int,
        typer.Option(
            "--replays",
            help="Replays written for the top of the ranking, each opening at its peak (-1: all).",
        ),
    ] = 20,
    reference_runs: Annotated[
        int,
        typer.Option(
            "--reference-runs",
            help="A task without known-good runs is judged against at most this many of its other episodes "
            "(a fixed sample), so memory stays flat however many episodes there are.",
        ),
    ] = 100,
    detector: DetectorConfig,
    camera_codec: CameraCodecOption = CameraCodec.AUTO,
) -> None:
    """Rank every episode of a dataset nobody labelled by how unlike normal runs it looks, to label the top.

    Each task is judged by --memory, else by its known-good runs (--successes, the success rows of --labels), else each episode against the task's other episodes (this assumes most runs succeeded).
    """
    from rfr_viz.jobs.triage import triage
    from robofailring.triage import TriageConfig

    outcome = triage(
        TriageConfig(
            data=data, out=out, detector=detector, known_good=known_good, reference_runs=reference_runs
        ),
        replays=replays,
        camera_codec=camera_codec,
    )
    result = outcome.result
    report_skipped(result.skipped_inputs)
    print_notes([f"note: {note}" for note in result.notes])
    typer.echo(outcome.summary(data.root))
    finish(skipped=len(result.skipped_inputs))
