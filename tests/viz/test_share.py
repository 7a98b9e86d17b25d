"""`robofailring share`: a folder of recordings served on 127.0.0.1, fetched over HTTP, and stopped."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest
import rerun as rr
from ports import free_port

from rfr_viz.viewer.share import _lan_address, share_folder
from robofailring.errors import DataError

pytestmark = pytest.mark.slow  # simulation or end-to-end: the full lane only (scripts/test.sh)


def _listening(port: int, host: str = "127.0.0.1") -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.3):
            return True
    except OSError:
        return False


def _recording(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("robofailring-share-test")
    rec.save(path)
    rec.log("note", rr.TextDocument(text), static=True)
    rec.flush()
    rec.disconnect()
    return path


@pytest.fixture()
def folder(tmp_path: Path) -> Path:
    _recording(tmp_path / "share" / "a.rrd", "first")
    _recording(tmp_path / "share" / "review" / "b.rrd", "second")
    return tmp_path / "share"


def test_share_serves_the_web_viewer_on_loopback_and_stops(folder: Path) -> None:
    grpc_port, web_port = free_port(), free_port()
    shared = share_folder(folder, grpc_port=grpc_port, web_port=web_port)
    try:
        assert [p.name for p in shared.recordings] == ["a.rrd", "b.rrd"]
        assert shared.grpc_url == f"rerun+http://127.0.0.1:{grpc_port}/proxy"
        assert shared.web_url.startswith(f"http://127.0.0.1:{web_port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1")
        with urllib.request.urlopen(shared.web_url, timeout=10) as response:
            page = response.read().decode("utf-8", errors="replace")
        assert response.status == 200 and "Rerun" in page
        lan = _lan_address()  # loopback only: not reachable on this machine's network address
        if re.fullmatch(r"[0-9.]+", lan) and not lan.startswith("127."):
            assert not _listening(web_port, lan) and not _listening(grpc_port, lan)
    finally:
        shared.stop()
    assert shared.process is not None and shared.process.poll() is not None
    assert not _listening(grpc_port) and not _listening(web_port)


def test_share_refuses_an_empty_folder_and_a_corrupt_file(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataError, match=r"no \.rrd recordings under"):
        share_folder(tmp_path / "empty")
    bad = tmp_path / "bad" / "broken.rrd"
    bad.parent.mkdir()
    bad.write_bytes(b"not a recording")
    with pytest.raises(DataError, match=r"broken\.rrd"):
        share_folder(bad.parent, grpc_port=free_port(), web_port=free_port())


def test_share_command_prints_the_urls_and_stops_on_ctrl_c(folder: Path) -> None:
    grpc_port, web_port = free_port(), free_port()
    command = [sys.executable, "-m", "rfr_viz.cli.app", "share", str(folder), "--port", str(grpc_port)]
    process = subprocess.Popen(
        [*command, "--web-port", str(web_port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env={**os.environ, "ROBOFAILRING_PROGRESS": "0"},
    )
    try:
        assert process.stdout is not None
        lines = []
        for line in process.stdout:
            lines.append(line)
            if "Ctrl-C" in line:
                break
        output = "".join(lines)
        assert "serving 2 recording(s)" in output, output
        assert f"http://127.0.0.1:{web_port}/?url=" in output
        assert f"rerun rerun+http://127.0.0.1:{grpc_port}/proxy" in output
        with urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=10) as response:
            assert response.status == 200
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=10)
    assert not _listening(grpc_port) and not _listening(web_port)
