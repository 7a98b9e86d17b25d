"""The `explain` and `watch` verbs: the VLM reasoning step afterwards, and a robot's run watched live."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer

from rfr_viz.panels.camera_video import CameraCodec, LiveCameraCodecOption
from robofailring.cli.options import (
    CacheOption,
    DataRootOption,
    DeviceOption,
    TaskOption,
    VLMModelOption,
    VLMUrlOption,
    exit_with_error,
    vlm_config,
)
from robofailring.errors import RoboFailRingError

app = typer.Typer(add_completion=False)  # composed into the one `robofailring` command by rfr_viz.cli.app


@app.command("explain")
def explain_cmd(
    source: Annotated[
        Path, typer.Argument(help="A recording written by replay/review, or the output of `detect --json`.")
    ],
    vlm_url: VLMUrlOption = None,
    vlm_model: VLMModelOption = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print {model, answer, latency_s} (or {model, error}) as JSON.")
    ] = False,
    data_root: DataRootOption = None,
) -> None:
    """Ask a VLM about the failure report of a detection made earlier (paper Appendix B)."""
    from rfr_viz.jobs.explain import read_report
    from robofailring.explain.vlm import ask_vlm

    vlm = vlm_config(vlm_url, vlm_model)
    if vlm is None:
        exit_with_error(ValueError("explain needs --vlm-url and --vlm-model"))
        return
    try:
        report = read_report(source)
    except RoboFailRingError as error:
        exit_with_error(error)
        return
    if data_root is not None:
        report = report.relocated(data_root)
    answer = ask_vlm(report, vlm)
    if as_json:
        json.dump(answer.to_dict(), sys.stdout)
        sys.stdout.write("\n")
    if answer.error is not None:
        typer.secho(f"error: the VLM call failed: {answer.error}", fg=typer.colors.RED, err=True)
        raise typer.Exit(code=1)
    if not as_json:
        typer.echo(
            f"{report.current_task}: failure at frame {report.t_det} in view {report.view} "
            f"(S_t = {report.similarity:.3f}); {answer.model} answered in {answer.latency_s:.1f} s:\n"
        )
        typer.echo(answer.answer)


@app.command("watch")
def watch_cmd(
    episode: Annotated[Path, typer.Argument(help="One episode folder, fed frame by frame as a robot would.")],
    memory: Annotated[Path, typer.Option("--memory", help="Memory directory.")],
    connect: Annotated[
        str | None,
        typer.Option(
            "--connect",
            help="gRPC URL of a running Rerun viewer (default rerun+http://127.0.0.1:9876/proxy, "
            "unless only --save is given).",
        ),
    ] = None,
    spawn: Annotated[bool, typer.Option("--spawn", help="Start a Rerun viewer and stream to it.")] = False,
    save: Annotated[
        Path | None, typer.Option("--save", help="Also write the same stream to this .rrd.")
    ] = None,
    task: TaskOption = None,
    delta: Annotated[
        float | None, typer.Option(help="Threshold δ (default: the memory's calibrated δ, else 0.92).")
    ] = None,
    k: Annotated[int, typer.Option(help="Neighbours retrieved per query.")] = 5,
    speed: Annotated[
        float,
        typer.Option(help="1: the data's frame rate; 2: twice as fast; 0: as fast as the detector goes."),
    ] = 1.0,
    fps: Annotated[float | None, typer.Option(help="Frame rate (default: the data's, else 10).")] = None,
    encoder: Annotated[str | None, typer.Option(help="Encoder spec (default: the memory's).")] = None,
    cache_dir: CacheOption = None,
    device: DeviceOption = None,
    data_root: DataRootOption = None,
    camera_codec: LiveCameraCodecOption = CameraCodec.JPEG,
) -> None:
    """Watch an episode live in the Rerun viewer: every step through the detector's step API, streamed."""
    from rfr_viz.jobs.watch import WatchConfig, watch
    from rfr_viz.recordings.live import DEFAULT_VIEWER_URL, LiveTarget
    from rfr_viz.viewer.control import ViewerUnavailable

    if connect is None and not spawn and save is None:
        connect = DEFAULT_VIEWER_URL
    try:
        result = watch(
            WatchConfig(
                episode=episode,
                memory=memory,
                target=LiveTarget(connect=connect, spawn=spawn, save=save),
                task=task,
                delta=delta,
                k=k,
                encoder=encoder,
                speed=speed,
                fps=fps,
                cache_dir=cache_dir,
                device=device,
                data_root=data_root,
                camera_codec=camera_codec,
            )
        )
    except (RoboFailRingError, ValueError, ViewerUnavailable) as error:
        exit_with_error(error)
        return
    if result.lost is not None:
        typer.secho(f"warning: {result.lost}", fg=typer.colors.YELLOW, err=True)
    if result.fired_at is None:
        typer.echo(f"{result.steps} steps watched: no failure detected")
    else:
        typer.echo(
            f"{result.steps} steps watched: FAILURE at frame {result.fired_at} in view {result.detected_view}"
        )
    if result.saved is not None:
        typer.echo(f"saved the stream to {result.saved}")
