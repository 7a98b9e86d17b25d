"""The `replay`, `compare`, `open` and `share` verbs: trajectories into recordings, and recordings into viewers."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rfr_viz.jobs.replay import DEFAULT_OUT, CompareConfig, ReplayConfig, ReplayResult, compare, replay
from rfr_viz.panels.camera_video import CameraCodec, CameraCodecOption
from rfr_viz.viewer.control import DEFAULT_PORT, ViewerUnavailable, open_at, open_command
from robofailring.cli.exit_codes import finish
from robofailring.cli.options import (
    CacheOption,
    DataRootOption,
    DeviceOption,
    GammaOption,
    LabelsOption,
    ScoreOption,
    StrideOption,
    TaskOption,
    VLMModelOption,
    VLMUrlOption,
    exit_with_error,
    report_skipped,
    vlm_config,
    warn_missing_references,
)
from robofailring.errors import DataError, RoboFailRingError
from robofailring.outputs import is_recording

app = typer.Typer(add_completion=False)  # composed into the one `robofailring` command by rfr_viz.cli.app

DataArgument = Annotated[
    Path, typer.Argument(help="Dataset root (any supported layout) or one episode folder.")
]
OutOption = Annotated[Path, typer.Option("--out", help="Folder for the .rrd files (one per trajectory).")]
TrajectoryOption = Annotated[
    list[str] | None,
    typer.Option(
        "--trajectory", help="Only this trajectory (`<task>/<episode>` or the episode); repeatable."
    ),
]
KOption = Annotated[int, typer.Option("--k", help="Neighbours retrieved and logged per view and frame.")]
LeaveOneOutOption = Annotated[
    bool, typer.Option("--leave-one-out", help="Hide each trajectory's own episode from the memory.")
]
FpsOption = Annotated[
    float | None,
    typer.Option("--fps", help="Frame rate of the `time` timeline (default: the data's, else 10)."),
]


def warn_vlm_errors(result: ReplayResult) -> None:
    """One stderr line per failed VLM call (the recordings are written all the same)."""
    for key, error in result.vlm_errors:
        typer.secho(f"warning: the VLM call failed for {key}: {error}", fg=typer.colors.YELLOW, err=True)


def _report(result: ReplayResult, out: Path) -> None:
    report_skipped(result.skipped_inputs)
    for memory_dir, check in result.references.items():
        warn_missing_references(memory_dir, check)
    warn_vlm_errors(result)
    for key, reason in result.skipped:
        typer.echo(f"skipped {key}: {reason}")
    if not result.recordings:
        exit_with_error(DataError(f"no recording written ({len(result.skipped)} trajectories skipped)"))
    typer.echo(
        f"{len(result.recordings)} recording(s) in {out.resolve()}"
        + (f", {len(result.skipped)} trajectories skipped" if result.skipped else "")
    )
    for path in result.recordings:
        typer.echo(f"  {open_command(path)}")
    finish(skipped=len(result.skipped))


@app.command("replay")
def replay_cmd(
    data: DataArgument,
    memory: Annotated[Path, typer.Option("--memory", help="Memory directory (its map is cached there).")],
    out: OutOption = DEFAULT_OUT,
    trajectory: TrajectoryOption = None,
    delta: Annotated[
        float | None, typer.Option(help="Threshold δ (default: the memory's calibrated δ, else 0.92).")
    ] = None,
    k: KOption = 5,
    score: ScoreOption = None,
    gamma: GammaOption = None,
    task: TaskOption = None,
    leave_one_out: LeaveOneOutOption = False,
    encoder: Annotated[str | None, typer.Option(help="Encoder spec (default: the memory's).")] = None,
    fps: FpsOption = None,
    stride: StrideOption = 1,
    labels: LabelsOption = None,
    camera_codec: CameraCodecOption = CameraCodec.AUTO,
    cache_dir: CacheOption = None,
    device: DeviceOption = None,
    data_root: DataRootOption = None,
    vlm_url: VLMUrlOption = None,
    vlm_model: VLMModelOption = None,
) -> None:
    """Replay trajectories through the detector, one self-contained Rerun recording (.rrd) each."""
    config = ReplayConfig(
        data=data,
        memory=memory,
        out=out,
        trajectories=tuple(trajectory or ()),
        delta=delta,
        k=k,
        score=score,
        gamma=gamma,
        task=task,
        leave_one_out=leave_one_out,
        encoder=encoder,
        fps=fps,
        camera_codec=camera_codec,
        cache_dir=cache_dir,
        device=device,
        stride=stride,
        labels=labels,
        data_root=data_root,
        vlm=vlm_config(vlm_url, vlm_model),
    )
    try:
        result = replay(config)
    except (RoboFailRingError, ValueError) as error:
        exit_with_error(error)
    _report(result, out)


@app.command("compare")
def compare_cmd(
    data: DataArgument,
    memory: Annotated[
        list[Path], typer.Option("--memory", help="Memory directory, one per encoder; give two or more.")
    ],
    out: OutOption = DEFAULT_OUT,
    trajectory: TrajectoryOption = None,
    delta: Annotated[
        list[float] | None,
        typer.Option(
            "--delta", help="δ per memory, in the order of --memory (default: each one's calibrated δ)."
        ),
    ] = None,
    k: KOption = 5,
    score: ScoreOption = None,
    task: TaskOption = None,
    leave_one_out: LeaveOneOutOption = False,
    fps: FpsOption = None,
    camera_codec: CameraCodecOption = CameraCodec.AUTO,
    cache_dir: CacheOption = None,
    device: DeviceOption = None,
    data_root: Annotated[
        list[Path] | None,
        typer.Option(
            "--data-root",
            help="Where the memories' dataset is now, when it moved: one for all, or one per --memory.",
        ),
    ] = None,
) -> None:
    """Replay trajectories under two or more encoders' memories, one comparison recording each."""
    config = CompareConfig(
        data=data,
        memories=tuple(memory),
        out=out,
        trajectories=tuple(trajectory or ()),
        deltas=tuple(delta or ()),
        k=k,
        score=score,
        task=task,
        leave_one_out=leave_one_out,
        fps=fps,
        camera_codec=camera_codec,
        cache_dir=cache_dir,
        device=device,
        data_roots=tuple(data_root or ()),
    )
    try:
        result = compare(config)
    except (RoboFailRingError, ValueError) as error:
        exit_with_error(error)
    _report(result, out)


@app.command("open")
def open_cmd(
    recording: Annotated[Path, typer.Argument(help="A .rrd written by replay, review, compare or the demo.")],
    frame: Annotated[
        int | None, typer.Option(help="Frame to pause at (default: the recording's alarm or focus).")
    ] = None,
    port: Annotated[int, typer.Option(help="Viewer port; a viewer already listening there is reused.")] = (
        DEFAULT_PORT
    ),
) -> None:
    """Open a recording in the Rerun viewer paused at its alarm (a review's false alarm, a miss's peak)."""
    if not recording.is_file():
        exit_with_error(DataError(f"no recording at {recording}"))
    if not is_recording(recording):
        exit_with_error(DataError(f"{recording} is not a Rerun recording (.rrd); open one that replay wrote"))
    try:
        opened = open_at(recording, frame, port=port)
    except (ViewerUnavailable, ValueError) as error:
        exit_with_error(error)
    started = "started a viewer" if opened.process is not None else "reused the viewer"
    typer.echo(f"{opened.recording}: paused at frame {opened.frame} ({started} on port {opened.port})")


@app.command("share")
def share_cmd(
    folder: Annotated[Path, typer.Argument(help="Folder of .rrd recordings (searched recursively).")],
    host: Annotated[
        str, typer.Option(help="Address to listen on: 127.0.0.1 (this machine only) or 0.0.0.0 (the LAN).")
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="gRPC port the viewers read the recordings from.")] = 9876,
    web_port: Annotated[int, typer.Option("--web-port", help="HTTP port of the web viewer.")] = 9090,
) -> None:
    """Serve a folder of recordings to the Rerun web viewer (and native viewers) until Ctrl-C."""
    import time

    from rfr_viz.viewer.share import share_folder

    try:
        shared = share_folder(folder, host=host, grpc_port=port, web_port=web_port)
    except (RoboFailRingError, ViewerUnavailable) as error:
        exit_with_error(error)
    try:
        typer.echo(f"serving {len(shared.recordings)} recording(s) from {folder} on {host}:")
        typer.echo(f"  web viewer:    {shared.web_url}")
        typer.echo(f"  native viewer: rerun {shared.grpc_url}")
        if host == "127.0.0.1":
            typer.echo("  (this machine only; --host 0.0.0.0 opens it to the LAN)")
        typer.echo("Ctrl-C stops it.")
        while shared.process is not None and shared.process.poll() is None:
            time.sleep(0.5)
        exit_with_error(
            RuntimeError(
                f"the Rerun server stopped (exit code {shared.process.returncode if shared.process else '?'})"
            )
        )
    except KeyboardInterrupt:
        typer.echo("stopped")
    finally:
        shared.stop()
