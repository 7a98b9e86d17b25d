"""The `replay`, `compare`, `open` and `share` verbs: trajectories into recordings, and recordings into viewers."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rfr_viz.cli.options import RECORDINGS
from rfr_viz.jobs.recorded import Recordings
from rfr_viz.viewer.control import DEFAULT_PORT, open_command
from robofailring.cli.exit_codes import finish
from robofailring.cli.groups import takes
from robofailring.cli.option_groups import DATA, DETECTOR, SCORING, VLM
from robofailring.cli.options import (
    StrideOption,
    print_notes,
    report_skipped,
    report_skipped_runs,
    warn_missing_references,
)
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_STRIDE, DetectorConfig
from robofailring.detection.rules import PAPER
from robofailring.errors import SettingError
from robofailring.explain.vlm import VLMConfig

if TYPE_CHECKING:
    from rfr_viz.jobs.replay import ReplayResult

app = typer.Typer(add_completion=False)  # composed into the one `robofailring` command by rfr_viz.cli.app


def warn_vlm_errors(result: ReplayResult) -> None:
    """One stderr line per failed VLM call (the recordings are written all the same)."""
    for key, error in result.vlm_errors:
        typer.secho(f"warning: the VLM call failed for {key}: {error}", fg=typer.colors.YELLOW, err=True)


def _report(result: ReplayResult, out: Path) -> None:
    report_skipped(result.skipped_inputs)
    for memory_dir, check in result.references.items():
        warn_missing_references(memory_dir, check)
    warn_vlm_errors(result)
    print_notes(result.notes)
    report_skipped_runs(result.skipped)
    finish(failure=result.failure)
    typer.echo(
        f"{len(result.recordings)} recording(s) in {out.resolve()}"
        + (f", {len(result.skipped)} trajectories skipped" if result.skipped else "")
    )
    for path in result.recordings:
        verdict = result.verdicts.get(path)
        typer.echo(f"  {open_command(path)}" + (f"\n    {verdict}" if verdict else ""))
    finish(skipped=len(result.skipped) + len(result.skipped_inputs))  # listed above


@app.command("replay")
@takes(data=DATA.without("vocabulary"), detector=DETECTOR.without("ray"), recordings=RECORDINGS, vlm=VLM)
def replay_cmd(
    data: DataSelection,
    *,
    detector: DetectorConfig,
    recordings: Recordings,
    stride: StrideOption = DEFAULT_STRIDE,
    vlm: VLMConfig | None,
) -> None:
    """Replay trajectories through the detector, one self-contained Rerun recording (.rrd) each."""
    from rfr_viz.jobs.replay import ReplayConfig, replay

    config = ReplayConfig(data=data, detector=detector, recordings=recordings, stride=stride, vlm=vlm)
    _report(replay(config), recordings.out)


@app.command("compare")
@takes(
    data=DATA.only("data", "task", "views"),
    recordings=RECORDINGS,
    # the settings every memory shares: how runs are scored (every scoring setting), the rule, where encoders run
    detector=DETECTOR.only("score", "cache_dir", "device", *SCORING.options()),
)
def compare_cmd(
    data: DataSelection,
    *,
    memory: Annotated[
        list[Path], typer.Option("--memory", help="Memory directory, one per encoder; give two or more.")
    ],
    recordings: Recordings,
    delta: Annotated[
        list[float] | None,
        typer.Option(
            "--delta", help="δ per memory, in the order of --memory.", show_default="each one's calibrated δ"
        ),
    ] = None,
    detector: DetectorConfig,
    data_root: Annotated[
        list[Path] | None,
        typer.Option(
            "--data-root",
            help="Where the memories' dataset is now, when it moved: one for all, or one per --memory.",
        ),
    ] = None,
) -> None:
    """Replay trajectories under two or more encoders' memories, one comparison recording each."""
    from rfr_viz.jobs.compare import CompareConfig, compare

    config = CompareConfig(
        data=data,
        detectors=compared_detectors(memory, deltas=delta or [], data_roots=data_root or [], shared=detector),
        recordings=recordings,
    )
    _report(compare(config), recordings.out)


def compared_detectors(
    memories: Sequence[Path], *, deltas: Sequence[float], data_roots: Sequence[Path], shared: DetectorConfig
) -> tuple[DetectorConfig, ...]:
    """One detector per --memory: `shared` settings, its own --delta (one per memory, or none) and
    --data-root (one for all, or one per memory)."""
    if deltas and len(deltas) != len(memories):
        raise SettingError(f"{len(deltas)} δ values for {len(memories)} memories: give one per memory")
    if len(data_roots) not in (0, 1, len(memories)):
        raise SettingError(
            f"{len(data_roots)} data roots for {len(memories)} memories: give one, or one per memory"
        )
    roots = list(data_roots) * len(memories) if len(data_roots) == 1 else list(data_roots)
    return tuple(
        shared.with_memory(
            memory,
            data_root=roots[position] if roots else None,
            thresholds={PAPER.name: deltas[position]} if deltas else {},
        )
        for position, memory in enumerate(memories)
    )


@app.command("open")
def open_cmd(
    recording: Annotated[Path, typer.Argument(help="A .rrd written by replay, review, compare or the demo.")],
    frame: Annotated[
        int | None, typer.Option(help="Frame to pause at.", show_default="the recording's alarm or focus")
    ] = None,
    port: Annotated[int, typer.Option(help="Viewer port; a viewer already listening there is reused.")] = (
        DEFAULT_PORT
    ),
) -> None:
    """Open a recording in the Rerun viewer paused at its alarm (a review's false alarm, a miss's peak)."""
    from rfr_viz.jobs.viewer import open_recording, opened_line

    typer.echo(opened_line(open_recording(recording, frame, port=port)))


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
    from rfr_viz.jobs.viewer import serve_recordings

    serve_recordings(folder, host=host, port=port, web_port=web_port, say=typer.echo)
