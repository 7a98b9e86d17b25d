"""The `explain` and `watch` verbs: the VLM reasoning step afterwards, and a robot's run watched live."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rfr_viz.cli.options import LiveCameraCodecOption
from rfr_viz.codecs import CameraCodec
from robofailring.cli.exit_codes import finish
from robofailring.cli.groups import Declared, takes
from robofailring.cli.option_groups import DATA, DETECTOR, VLM
from robofailring.cli.options import FpsOption, report_skipped
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.explain.vlm import VLMConfig

app = typer.Typer(add_completion=False)  # composed into the one `robofailring` command by rfr_viz.cli.app


@app.command("explain")
@takes(vlm=VLM, detector=DETECTOR.only("data_root"))
def explain_cmd(
    source: Annotated[
        Path, typer.Argument(help="A recording written by replay/review, or the output of `detect --json`.")
    ],
    *,
    vlm: VLMConfig | None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print {model, answer, latency_s} (or {model, error}) as JSON.")
    ] = False,
    detector: DetectorConfig,
) -> None:
    """Ask a VLM about the failure report of a detection made earlier (paper Appendix B)."""
    from rfr_viz.jobs.explain import explain

    explanation = explain(source, vlm, data_root=detector.data_root)
    if as_json:
        typer.echo(explanation.to_json())  # printed even when the call failed: it says why
    finish(failure=explanation.failure)
    if not as_json:
        typer.echo(explanation.to_text())


@app.command("watch")
@takes(
    data=DATA.only("data", "task", "views").but(
        data=Declared(
            Annotated[Path, typer.Argument(help="One episode folder, fed frame by frame as a robot would.")],
            name="episode",
        )
    ),
    detector=DETECTOR.without("ray"),
)
def watch_cmd(
    data: DataSelection,
    *,
    connect: Annotated[
        str | None,
        typer.Option(
            "--connect",
            help="gRPC URL of a running Rerun viewer.",
            show_default="rerun+http://127.0.0.1:9876/proxy, unless only --save is given",
        ),
    ] = None,
    spawn: Annotated[bool, typer.Option("--spawn", help="Start a Rerun viewer and stream to it.")] = False,
    save: Annotated[
        Path | None, typer.Option("--save", help="Also write the same stream to this .rrd.")
    ] = None,
    detector: DetectorConfig,
    speed: Annotated[
        float,
        typer.Option(help="1: the data's frame rate; 2: twice as fast; 0: as fast as the detector goes."),
    ] = 1.0,
    fps: FpsOption = None,
    camera_codec: LiveCameraCodecOption = CameraCodec.JPEG,
) -> None:
    """Watch an episode live in the Rerun viewer: every step through the detector's step API, streamed."""
    from rfr_viz.jobs.watch import WatchConfig, watch
    from rfr_viz.recordings.live_target import LiveTarget

    result = watch(
        WatchConfig(
            data=data,
            detector=detector,
            target=LiveTarget.chosen(connect=connect, spawn=spawn, save=save),
            speed=speed,
            fps=fps,
            camera_codec=camera_codec,
        )
    )
    if result.lost is not None:
        typer.secho(f"warning: {result.lost}", fg=typer.colors.YELLOW, err=True)
    report_skipped(result.blind)
    typer.echo(result.to_text())
    finish(skipped=len(result.blind))  # listed above: a blind camera's "no alarm" is not a clean run
