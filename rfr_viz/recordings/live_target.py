"""Where a live recording goes (`LiveTarget`: a running viewer, a spawned one, a file), the check that a
viewer listens where one is named, and the stream's sinks opened on them."""

from __future__ import annotations

import contextlib
import socket
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from rfr_viz.viewer.binary import ViewerUnavailable
from rfr_viz.viewer.control import DEFAULT_PORT
from rfr_viz.viewer.rrd import check_recording_file
from robofailring.atomic import atomic_path
from robofailring.errors import SettingError
from robofailring.extras import needs_extra

if TYPE_CHECKING:
    import rerun as rr

DEFAULT_VIEWER_URL: Final[str] = f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy"


@dataclass(frozen=True)
class LiveTarget:
    """Where the live stream goes: a running viewer, a spawned one, and/or a file."""

    connect: str | None = None  # gRPC URL of a running viewer, e.g. rerun+http://127.0.0.1:9876/proxy
    spawn: bool = False  # start a viewer on the default port and stream to it
    save: Path | None = None  # also write the same stream to this .rrd (atomically, at the end)

    def __post_init__(self) -> None:
        if self.connect is None and not self.spawn and self.save is None:
            raise SettingError("a live recording needs somewhere to go: a viewer URL, spawn, or a file")

    @classmethod
    def chosen(cls, *, connect: str | None, spawn: bool, save: Path | None) -> LiveTarget:
        """The target a user asked for; none at all: the viewer on the default port."""
        if connect is None and not spawn and save is None:
            connect = DEFAULT_VIEWER_URL
        return cls(connect=connect, spawn=spawn, save=save)

    def check(self) -> None:
        """Before any work: a file to save to is not one robofailring did not write (a memory's manifest, a
        labels file, a frame), and would be replaced (`check_recording_file`)."""
        if self.save is not None:
            check_recording_file(Path(self.save))

    def send(self, rec: rr.RecordingStream, stack: ExitStack, blueprint: Any) -> str | None:
        """`rec` sent here with `blueprint` as its layout: the file (claimed in `stack`: a second writer of
        it stops at once, a file put there meanwhile stays; moved into place when `stack` closes), a viewer
        spawned, and a running one checked to listen first; the viewer's URL, if any."""
        with needs_extra("viz"):
            import rerun as rr

        sinks: list[Any] = []
        if self.save is not None:  # no footer: its chunk manifest would grow with every step held in RAM
            saved = stack.enter_context(atomic_path(Path(self.save), suffix=".rrd", claim=True))
            sinks.append(rr.FileSink(saved, write_footer=False))
        url = self.connect
        if url is not None:
            check_viewer(url)
        if self.spawn:
            rec.spawn(port=DEFAULT_PORT, connect=False, hide_welcome_screen=True)
            url = url or DEFAULT_VIEWER_URL
        if url is not None:
            sinks.append(rr.GrpcSink(url))
        rec.set_sinks(*sinks, default_blueprint=blueprint)
        return url


def check_viewer(url: str) -> None:
    """ViewerUnavailable unless something listens at the host and port of a viewer URL."""
    from urllib.parse import urlparse

    parsed = urlparse(url)
    if not parsed.scheme.startswith("rerun") or parsed.hostname is None:
        raise SettingError(f"viewer URL {url!r} is not like rerun+http://127.0.0.1:9876/proxy")
    port = parsed.port or DEFAULT_PORT
    with contextlib.suppress(OSError), socket.create_connection((parsed.hostname, port), timeout=2.0):
        return
    raise ViewerUnavailable(
        f"no Rerun viewer listens at {url}: start one (`rerun`), pass --spawn, or only --save to a file"
    )
