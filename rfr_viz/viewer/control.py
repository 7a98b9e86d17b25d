"""Render a recording in the real Rerun viewer, headless, to a PNG (for tests, docs and reviews)."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Final

from rfr_viz.paths import FRAME
from rfr_viz.viewer.binary import ViewerUnavailable, check_vulkan, viewer_binary, viewer_environment
from rfr_viz.viewer.rrd import focus_frame, verify_recording
from robofailring.extras import needs_extra

if TYPE_CHECKING:
    from rerun.experimental import Recording, ViewerClient, ViewerState

WINDOW: Final[tuple[int, int]] = (1280, 720)


@dataclass(frozen=True)
class Screenshot:
    """A rendered recording: the PNG, and the viewer's ERROR log lines while it showed it."""

    path: Path
    errors: list[str] = field(default_factory=list)
    frame: int | None = None
    views: dict[str, bytes] = field(default_factory=dict)  # PNG of each view asked for, by origin


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _listening(port: int) -> bool:
    with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), timeout=0.2):
        return True
    return False


def _wait_for_port(port: int, process: subprocess.Popen[bytes], deadline: float) -> None:
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise ViewerUnavailable(f"the viewer exited with code {process.returncode} before listening")
        if _listening(port):
            return
        time.sleep(0.05)
    raise TimeoutError(f"the viewer did not listen on port {port} in time")


def _viewer_command(port: int, *, headless: bool, size: tuple[int, int] = WINDOW) -> list[str]:
    command = [str(viewer_binary()), "--bind", "127.0.0.1", "--port", str(port), "--hide-welcome-screen"]
    if headless:
        command += ["--headless", "--window-size", f"{size[0]}x{size[1]}"]
    return command


@contextlib.contextmanager
def _viewer_process(size: tuple[int, int], deadline: float) -> Iterator[int]:
    """The headless viewer in its own process group, stopped (group and all) on exit."""
    with tempfile.TemporaryDirectory(prefix="rfr-viewer-") as runtime_dir:
        os.chmod(runtime_dir, 0o700)
        port = _free_port()
        log_path = Path(runtime_dir) / "viewer.log"
        with log_path.open("wb") as log:
            process = subprocess.Popen(
                _viewer_command(port, headless=True, size=size),
                env=viewer_environment(runtime_dir),
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
            try:
                try:
                    _wait_for_port(port, process, deadline)
                except ViewerUnavailable as error:
                    tail = log_path.read_text(errors="replace")[-2000:]
                    raise ViewerUnavailable(f"{error}; viewer output:\n{tail}") from error
                yield port
            finally:
                stop_viewer(process)


def stop_viewer(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGTERM)
    try:
        process.wait(timeout=5)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=5)


def render_screenshot(
    recording: Path,
    out: Path,
    *,
    frame: int | None = None,
    size: tuple[int, int] = WINDOW,
    settle: float = 0.5,
    timeout: float = 90.0,
    views: Sequence[str] = (),
) -> Screenshot:
    """Open `recording` in the headless viewer at `size`, pause at `frame` and save a PNG at `out`.

    The recording is verified first; `settle` seconds pass before the shot (pop-ups fade after ~5 s).
    Returns the PNG and the viewer's ERROR log lines (a bad image shows up there, not in the view),
    plus a PNG of each view whose origin is in `views` (e.g. "/camera/front").
    Raises ViewerUnavailable where the viewer cannot run (no Vulkan driver).
    """
    recording = Path(recording).resolve()
    out = Path(out).resolve()
    check_vulkan()
    verify_recording(recording)
    deadline = time.monotonic() + timeout
    with _viewer_process(size, deadline) as port:
        client, timelines = _show(port, recording, deadline, require_frame=frame is not None)
        if frame is not None:
            client.set_time(FRAME, sequence=frame, play_state="paused")
        elif timelines:  # stay where the viewer opened it
            client.set_time(FRAME if FRAME in timelines else timelines[0], play_state="paused")
        time.sleep(settle)  # frames for images to decode and plots to settle
        out.parent.mkdir(parents=True, exist_ok=True)
        client.save_screenshot(str(out))
        shown = {view.origin: view.view_id for view in client.get_state().views}
        captured = {origin: client.take_screenshot(shown[origin]) for origin in views if origin in shown}
        errors = [f"{entry.target}: {entry.message}" for entry in client.get_logs() if entry.level == "ERROR"]
        errors += [
            f"view {view.name!r}: {report}"
            for view in client.get_state().views
            for report in view.reports or []
        ]
    if not out.is_file():
        raise RuntimeError(f"the viewer wrote no screenshot to {out}")
    return Screenshot(path=out, errors=errors, frame=frame, views=captured)


def playback_positions(
    recording: Path,
    *,
    seconds: float = 10.0,
    interval: float = 0.2,
    size: tuple[int, int] = WINDOW,
    timeout: float = 90.0,
) -> list[int | None]:
    """Open `recording` as a person would (no seeking) and sample the `frame` cursor for `seconds`.

    Shows what a reviewer sees on opening a file: where playback starts, and whether the
    blueprint's loop keeps it around an alarm. Raises ViewerUnavailable where the viewer cannot run.
    """
    recording = Path(recording).resolve()
    check_vulkan()
    deadline = time.monotonic() + timeout
    positions: list[int | None] = []
    with _viewer_process(size, deadline) as port:
        client, _ = _show(port, recording, deadline, require_frame=True)
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            active = _active_recording(client.get_state())
            on_frame = active is not None and active.current_timeline == FRAME
            positions.append(active.current_time if active is not None and on_frame else None)
            time.sleep(interval)
    return positions


def _show(
    port: int, recording: Path, deadline: float, *, require_frame: bool = False
) -> tuple[ViewerClient, list[str]]:
    """Open `recording` in the viewer on `port`, wait until it is loaded, and return the client and
    the recording's timelines; with `require_frame`, a recording without the `frame` timeline is a
    ValueError naming the file."""
    with needs_extra("viz"):
        from rerun.experimental import ViewerClient

    client = ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy")
    client.open(str(recording))
    timelines = _wait_loaded(client, deadline)
    if require_frame and FRAME not in timelines:
        raise ValueError(f"{recording} has no {FRAME!r} timeline (it has {timelines})")
    return client, timelines


def _wait_loaded(client: ViewerClient, deadline: float, *, grace: float = 2.0) -> list[str]:
    """Poll the viewer until the recording is loaded; return its timeline names.

    A recording shows up before its data, so one without timelines counts as loaded only after
    nothing has been loading for `grace` seconds (a recording of static data has no timeline).
    """
    idle_since: float | None = None
    while time.monotonic() < deadline:
        state = client.get_state()
        active = _active_recording(state)
        if active is not None and not state.loading:
            names = [timeline.name for timeline in active.timelines]
            if names:
                return names
            idle_since = idle_since or time.monotonic()
            if time.monotonic() - idle_since >= grace:
                return []
        else:
            idle_since = None
        time.sleep(0.1)
    raise TimeoutError("the viewer did not finish loading the recording in time")


def _active_recording(state: ViewerState) -> Recording | None:
    if state.active_recording is None:
        return None
    return next((r for r in state.recordings if r.store_id == state.active_recording), None)


DEFAULT_PORT: Final[int] = 9876  # the Rerun viewer's default: an already running viewer is reused


@dataclass
class OpenedRecording:
    """A recording shown in a viewer with the cursor paused at `frame`."""

    recording: Path
    frame: int
    port: int
    process: subprocess.Popen[bytes] | None = None  # the viewer started for it; None: one already running
    runtime_dir: str | None = None

    def close(self) -> None:
        """Stop the viewer if it was started here (a viewer that was already running is left alone)."""
        if self.process is not None:
            stop_viewer(self.process)
        if self.runtime_dir is not None:
            shutil.rmtree(self.runtime_dir, ignore_errors=True)


def open_at(
    recording: Path,
    frame: int | None = None,
    *,
    port: int = DEFAULT_PORT,
    headless: bool = False,
    timeout: float = 60.0,
) -> OpenedRecording:
    """Show `recording` in a Rerun viewer with the time cursor paused at `frame`.

    `frame` defaults to the recording's focus (`focus_frame`): a review recording opens at its
    alarm, which a saved blueprint cannot do. A viewer already listening on `port` is reused;
    otherwise one is started there (a window, or `headless` for tests) and keeps running after
    this returns: `close()` stops it.
    """

    recording = Path(recording).resolve()
    verify_recording(recording)
    frame = focus_frame(recording) if frame is None else frame
    deadline = time.monotonic() + timeout
    opened = OpenedRecording(recording=recording, frame=frame, port=port)
    if not _listening(port):
        if headless:
            check_vulkan()
        opened.runtime_dir = tempfile.mkdtemp(prefix="rfr-viewer-")
        os.chmod(opened.runtime_dir, 0o700)
        env = viewer_environment(opened.runtime_dir) if headless else {**os.environ, "RERUN_ANALYTICS": "0"}
        log_path = Path(opened.runtime_dir) / "viewer.log"
        with log_path.open("wb") as log:
            opened.process = subprocess.Popen(
                _viewer_command(port, headless=headless),
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,  # the viewer outlives this command
            )
        try:
            _wait_for_port(port, opened.process, deadline)
        except (ViewerUnavailable, TimeoutError) as error:
            tail = log_path.read_text(errors="replace").strip()[-1500:]
            opened.close()
            raise ViewerUnavailable(
                f"the Rerun viewer could not start on port {port} ({error}); is there a display? "
                f"Without one, `rerun --serve-web {recording}` serves it to a browser. Viewer output:\n{tail}"
            ) from error
    try:
        client, _ = _show(port, recording, deadline, require_frame=True)
        client.set_time(FRAME, sequence=frame, play_state="paused")
    except (OSError, RuntimeError, TimeoutError) as error:
        opened.close()
        raise ViewerUnavailable(
            f"could not show {recording} in the viewer on port {port}: {error} "
            "(is something other than a Rerun viewer listening there? pass another --port)"
        ) from error
    except BaseException:
        opened.close()
        raise
    return opened


def _script(name: str) -> str:
    """A console script by name: bare when on PATH, else the one beside this Python (the venv's)."""
    import sys

    script = Path(sys.executable).with_name(name)
    return name if shutil.which(name) or not script.exists() else str(script)


def open_command(recording: Path) -> str:
    """The shell line that opens a recording in the Rerun viewer (the venv's `rerun` when not on PATH)."""
    return f"{_script('rerun')} {recording}"


def open_at_command(recording: Path) -> str:
    """The shell line that opens a recording paused at its focus frame (`robofailring open`)."""
    return f"{_script('robofailring')} open {recording}"
