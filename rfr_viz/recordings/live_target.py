"""Where a live recording goes (`LiveTarget`: a running viewer, a spawned one, a file) and the check that a
viewer listens where one is named."""

from __future__ import annotations

import contextlib
import socket
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from rfr_viz.viewer.binary import ViewerUnavailable
from rfr_viz.viewer.control import DEFAULT_PORT
from robofailring.errors import SettingError

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
