"""Recordings shown inline in a Jupyter notebook: `show(path or trace)`, with the recording's own blueprint.

An `.rrd` written by this project holds its blueprint (the layout of a replay, a comparison, an
evaluation) as a blueprint store beside the data, saved as the application's default
(`open_recording`: `save(..., default_blueprint=...)`). `show` sends the whole file to
rerun-notebook's viewer, blueprint store included, so the inline viewer lays it out exactly as
`rerun FILE.rrd` does. A `DetectionTrace` is first recorded by `record_replay`, the replay verb's
own path, then shown the same way. Showing a file needs the `notebook` extra; recording a trace
needs `viz` as well.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from robofailring.detection.trace import DetectionTrace
from robofailring.errors import DataError, SettingError
from robofailring.extras import needs_extra
from robofailring.outputs import is_recording

with needs_extra("notebook"):
    import rerun_notebook  # noqa: F401  (rerun.notebook.Viewer's widget: a missing one names the extra here)
    from rerun.notebook import Viewer

if TYPE_CHECKING:
    from rfr_viz.panels.umap import MemoryMap
    from robofailring.data.model import Trajectory

#: The viewer's size in the cell: the notebook's width and a 16:9 height (a replay has cameras, plots and maps).
AUTO: Literal["auto"] = "auto"


@dataclass(frozen=True)
class InlineRecording:
    """What `show` put in the cell: the viewer and the recording it was sent (its blueprint included)."""

    viewer: Viewer  # rerun.notebook.Viewer: `set_time_ctrl`, `update_panels`, `on_event` work on it
    recording_bytes: int  # the size of the `.rrd` sent to the viewer
    path: Path | None  # the file shown (a trace's recording: its `out=`, None when it was a temporary file)

    def display(self) -> None:
        """Show the viewer (again) in the current cell."""
        self.viewer.display()

    def _ipython_display_(self) -> None:
        """Nothing: `show` has displayed the viewer already (a cell ending in `show(...)` shows it once)."""


def show(
    source: Path | str | DetectionTrace,
    *,
    trajectory: Trajectory | None = None,
    memory_map: MemoryMap | None = None,
    focus_frame: int | None = None,
    out: Path | None = None,
    width: int | Literal["auto"] = AUTO,
    height: int | Literal["auto"] = AUTO,
    display: bool = True,
) -> InlineRecording:
    """Show a recording inline in a notebook: an `.rrd` path, or a `DetectionTrace` with its `trajectory`.

    A trace is recorded with `record_replay` (`memory_map`, `focus_frame` as there) to `out`, or to a
    temporary file removed once sent. `display=False` only builds the viewer (`.display()` shows it).
    """
    if isinstance(source, DetectionTrace):
        trace = source

        def record(target: Path) -> bytes:
            replay = _record_trace(
                trace, trajectory=trajectory, memory_map=memory_map, focus_frame=focus_frame, out=target
            )
            return replay.read_bytes()

        if out is not None:
            data, shown = record(Path(out)), Path(out)
        else:
            with tempfile.TemporaryDirectory(prefix="rfr-show-") as folder:
                data, shown = record(Path(folder) / "replay.rrd"), None
    else:
        if trajectory is not None or memory_map is not None or focus_frame is not None or out is not None:
            raise SettingError(
                "trajectory=, memory_map=, focus_frame= and out= are for a trace, not a recording"
            )
        shown = Path(source)
        data = _read_recording(shown)
    viewer = Viewer(width=width, height=height, use_global_recording=False)
    # The widget's own `send_rrd` takes a whole `.rrd` file (rerun_notebook.Viewer); rerun.notebook.Viewer
    # holds it as `_viewer` and sends only what a live RecordingStream logs, so the file goes to it directly.
    viewer._viewer.send_rrd(data)
    if display:
        viewer.display()
    return InlineRecording(viewer=viewer, recording_bytes=len(data), path=shown)


def _read_recording(path: Path) -> bytes:
    """The bytes of a recording a user named: a missing or foreign file is a DataError naming it."""
    if not path.is_file():
        raise DataError(f"no recording at {path}")
    if not is_recording(path):
        raise DataError(f"{path} is not a Rerun recording (.rrd); show one that replay wrote")
    return path.read_bytes()


def _record_trace(
    trace: DetectionTrace,
    *,
    trajectory: Trajectory | None,
    memory_map: MemoryMap | None,
    focus_frame: int | None,
    out: Path,
) -> Path:
    """The trace's replay recording at `out` (`record_replay`, what the replay verb writes)."""
    if trajectory is None:
        raise SettingError("show(trace) needs the trajectory it was scored on: show(trace, trajectory=...)")
    if (trajectory.task, trajectory.episode) != (trace.task, trace.episode):
        raise SettingError(
            f"the trace is of {trace.task}/{trace.episode}, the trajectory is {trajectory.key}"
        )
    from rfr_viz.recordings.replay import record_replay  # the viz extra, only when a trace is recorded

    return record_replay(trajectory, trace, out=out, memory_map=memory_map, focus_frame=focus_frame)
