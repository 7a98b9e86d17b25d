"""The viewer jobs: `open` (one recording paused at its alarm) and `share` (a folder served until Ctrl-C)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from rfr_viz.viewer.binary import ViewerUnavailable
from rfr_viz.viewer.control import DEFAULT_PORT, OpenedRecording, open_at
from rfr_viz.viewer.share import DEFAULT_GRPC_PORT, DEFAULT_HOST, DEFAULT_WEB_PORT, share_folder
from robofailring.errors import DataError
from robofailring.outputs import is_recording


def open_recording(recording: Path, frame: int | None = None, *, port: int = DEFAULT_PORT) -> OpenedRecording:
    """`open_at`, for a path a user typed: a missing, foreign or damaged file is a DataError naming it."""
    if not recording.is_file():
        raise DataError(f"no recording at {recording}")
    if not is_recording(recording):
        raise DataError(f"{recording} is not a Rerun recording (.rrd); open one that replay wrote")
    try:
        return open_at(recording, frame, port=port)
    except ValueError as error:  # the viewer's verdict: a damaged recording, or one without a frame timeline
        raise DataError(str(error)) from error


def opened_line(opened: OpenedRecording) -> str:
    """What `robofailring open` says: where the recording is paused, and which viewer shows it."""
    started = "started a viewer" if opened.process is not None else "reused the viewer"
    return f"{opened.recording}: paused at frame {opened.frame} ({started} on port {opened.port})"


def serve_recordings(
    folder: Path,
    *,
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_GRPC_PORT,
    web_port: int = DEFAULT_WEB_PORT,
    say: Callable[[str], None] = print,
) -> None:
    """Serve a folder of recordings until Ctrl-C; a server that stops by itself is ViewerUnavailable."""
    shared = share_folder(folder, host=host, grpc_port=port, web_port=web_port)
    try:
        say(f"serving {len(shared.recordings)} recording(s) from {folder} on {host}:")
        say(f"  web viewer:    {shared.web_url}")
        say(f"  native viewer: rerun {shared.grpc_url}")
        if host == "127.0.0.1":
            say("  (this machine only; --host 0.0.0.0 opens it to the LAN)")
        say("Ctrl-C stops it.")
        while shared.process is not None and shared.process.poll() is None:
            time.sleep(0.5)
        code = shared.process.returncode if shared.process is not None else "?"
        raise ViewerUnavailable(f"the Rerun server stopped (exit code {code})")
    except KeyboardInterrupt:
        say("stopped")
    finally:
        shared.stop()
