"""`robofailring share DIR`: serve a folder of recordings to Rerun viewers (web and native) on the network.

The Rerun viewer binary serves the files (`--serve-web --bind HOST`): a gRPC server holding the
recordings and the web viewer over HTTP, both bound to HOST only. Loopback (127.0.0.1) by default;
`--host 0.0.0.0` opens them to the LAN. (`rr.serve_grpc` and `rr.serve_web_viewer` of rerun-sdk 0.41
always listen on every interface, so they are not used here.)
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from rfr_viz.viewer.binary import viewer_binary, viewer_environment
from rfr_viz.viewer.control import stop_viewer
from rfr_viz.viewer.rrd import verify_recording
from robofailring.errors import DataError

DEFAULT_HOST: Final[str] = "127.0.0.1"
DEFAULT_GRPC_PORT: Final[int] = 9876
DEFAULT_WEB_PORT: Final[int] = 9090
MEMORY_FLOOR: Final[int] = 512 * 1024 * 1024  # the server keeps all recordings in memory for late viewers


@dataclass
class SharedFolder:
    """A running server of recordings; `stop()` ends it (the process group it started)."""

    recordings: list[Path]
    host: str
    grpc_port: int
    web_port: int
    process: subprocess.Popen[bytes] | None = None
    runtime_dir: str | None = None
    log: Path | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def address(self) -> str:
        """The address other machines use: the LAN address when bound to every interface."""
        return _lan_address() if self.host in ("0.0.0.0", "::") else self.host

    @property
    def grpc_url(self) -> str:
        return f"rerun+http://{self.address}:{self.grpc_port}/proxy"

    @property
    def web_url(self) -> str:
        return f"http://{self.address}:{self.web_port}/?url={urllib.parse.quote(self.grpc_url, safe='')}"

    def stop(self) -> None:
        if self.process is not None:
            stop_viewer(self.process)
        if self.runtime_dir is not None:
            shutil.rmtree(self.runtime_dir, ignore_errors=True)


def _lan_address() -> str:
    """This machine's address on its default route (no packet is sent), else its host name."""
    with contextlib.suppress(OSError), socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.connect(("10.255.255.255", 1))
        return str(probe.getsockname()[0])
    return socket.gethostname()


def _listening(host: str, port: int) -> bool:
    target = "127.0.0.1" if host in ("0.0.0.0", "::") else host
    with contextlib.suppress(OSError), socket.create_connection((target, port), timeout=0.2):
        return True
    return False


def share_folder(
    folder: Path,
    *,
    host: str = DEFAULT_HOST,
    grpc_port: int = DEFAULT_GRPC_PORT,
    web_port: int = DEFAULT_WEB_PORT,
    timeout: float = 60.0,
) -> SharedFolder:
    """Start serving every `.rrd` under `folder` (verified first); returns once both ports listen."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(f"{folder} is not a folder of recordings")
    recordings = sorted(folder.rglob("*.rrd"))
    if not recordings:
        raise DataError(f"no .rrd recordings under {folder}")
    for recording in recordings:
        try:
            verify_recording(recording)
        except ValueError as error:
            raise DataError(str(error)) from error
    for port in (grpc_port, web_port):
        if _listening(host, port):
            raise DataError(f"port {port} on {host} is already in use: pass another --port / --web-port")
    shared = SharedFolder(recordings=recordings, host=host, grpc_port=grpc_port, web_port=web_port)
    memory = max(MEMORY_FLOOR, 2 * sum(path.stat().st_size for path in recordings))
    shared.runtime_dir = tempfile.mkdtemp(prefix="rfr-share-")
    os.chmod(shared.runtime_dir, 0o700)
    shared.log = Path(shared.runtime_dir) / "server.log"
    command = [
        str(viewer_binary()),
        "--serve-web",
        "--bind", host,
        "--port", str(grpc_port),
        "--web-viewer-port", str(web_port),
        "--server-memory-limit", f"{memory // (1024 * 1024)}MiB",
        *(str(path) for path in recordings),
    ]  # fmt: skip
    with shared.log.open("wb") as log:
        shared.process = subprocess.Popen(
            command,
            env=viewer_environment(shared.runtime_dir),
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    deadline = time.monotonic() + timeout
    while not (_listening(host, grpc_port) and _listening(host, web_port)):
        if shared.process.poll() is not None or time.monotonic() > deadline:
            tail = shared.log.read_text(errors="replace")[-1500:]
            shared.stop()
            raise DataError(f"the Rerun server did not start on {host}:{grpc_port}/{web_port}:\n{tail}")
        time.sleep(0.1)
    return shared
