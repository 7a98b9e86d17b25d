"""The `triage` verb: rank the episodes of a dataset nobody labelled (docs/triage.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rfr_viz.cli.options import CameraCodecOption
from rfr_viz.codecs import CameraCodec
from robofailring.cli.exit_codes import finish
from robofailring.cli.options import (
    DETECTOR_DEFAULTS,
    CacheOption,
    DataArgument,
    DataRootOption,
    DeviceOption,
    KOption,
    LabelsOption,
    RayOption,
    ReferenceEncoderOption,
    RuntimeOption,
    ScoreOption,
    TaskOption,
    ViewsOption,
    detector_config,
    print_notes,
    report_skipped,
)

app = typer.Typer(add_completion=False)  # composed into the one `robofailring` command by rfr_viz.cli.app


@app.command("triage")
def triage_cmd(
    data: DataArgument,
    out: Annotated[
        Path, typer.Option("--out", help="Folder for triage.csv, triage.rrd, triage.html and replays/.")
    ],
    memory: Annotated[
        Path | None,
        typer.Option("--memory", help="Judge by this memory, its rules as calibrated (its encoder)."),
    ] = None,
    successes: Annotated[
        Path | None,
        typer.Option(
            "--successes",
            help="A dataset of known-good runs (any layout; every episode a success): a success memory of "
            "them judges their tasks.",
        ),
    ] = None,
    labels: LabelsOption = None,
    encoder: ReferenceEncoderOption = None,
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
    k: KOption = DETECTOR_DEFAULTS.k,
    score: ScoreOption = None,
    task: TaskOption = None,
    views: ViewsOption = None,
    camera_codec: CameraCodecOption = CameraCodec.AUTO,
    cache_dir: CacheOption = None,
    device: DeviceOption = None,
    runtime: RuntimeOption = None,
    ray: RayOption = None,
    data_root: DataRootOption = None,
) -> None:
    """Rank every episode of a dataset nobody labelled by how unlike normal runs it looks, to label the top.

    Each task is judged by --memory, else by its known-good runs (--successes, the success rows of --labels), else each episode against the task's other episodes (this assumes most runs succeeded).
    """
    from rfr_viz.jobs.triage import triage
    from robofailring.triage import TriageConfig

    outcome = triage(
        TriageConfig(
            data=data,
            out=out,
            detector=detector_config(
                memory,
                encoder=encoder,
                device=device,
                runtime=runtime,
                cache_dir=cache_dir,
                data_root=data_root,
                k=k,
                score=score,
            ),
            successes=successes,
            labels=labels,
            task=task,
            views=views,
            reference_runs=reference_runs,
            ray=ray,
        ),
        replays=replays,
        camera_codec=camera_codec,
    )
    result = outcome.result
    report_skipped(result.skipped_inputs)
    print_notes([f"note: {note}" for note in result.notes])
    typer.echo(outcome.summary(data))
    finish(skipped=len(result.skipped_inputs))
