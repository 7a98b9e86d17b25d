"""Inputs this user may not read (issue 35, item 9): an error of the environment, status 1, naming what
cannot be read — not a bad input (2) and never "cannot write".

Root reads every file whatever its mode, so each case runs twice: in-process with the file system's
`PermissionError` raised where the file is opened, and for real, `chmod 000`, in a subprocess that may not
read it (when the tests run as root: root with every capability dropped, for whom mode bits hold).
"""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from environment import missing
from fault_helpers import cli, refused
from synthetic import write_aha_dataset

import rfr_viz
import robofailring
from robofailring import load_trajectory
from robofailring.cli.exit_codes import exit_code_for
from robofailring.data.model import Frame
from robofailring.errors import ReadError

EPISODE = "pick_cube_grasp_wp2_episode0"  # an episode of the `data` fixture (tests/cli/conftest.py)


def denied_for(monkeypatch: pytest.MonkeyPatch, locked: Path) -> None:
    """`locked` cannot be opened, as a file of mode 000 is for a user other than root."""
    real = Path.read_bytes

    def read_bytes(self: Path) -> bytes:
        if self.absolute() == locked.absolute():
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", read_bytes)


def test_a_frame_that_may_not_be_read_is_an_error_of_the_environment(
    data: Path, memory: Path, cache: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    locked = data / EPISODE / "front_1.png"
    denied_for(monkeypatch, locked)
    frame = Frame(path=locked)
    for read in (frame.load, frame.content_key):
        with pytest.raises(ReadError, match=r"cannot read image .*front_1\.png") as raised:
            read()
        assert exit_code_for(raised.value) == 1
    trajectory = load_trajectory(data / EPISODE)  # listing the folder needs no frame read
    assert [frame.path for frame in trajectory.views["front"]][1] == locked
    refused(cli("detect", data / EPISODE, "--memory", memory, *cache), 1, "cannot read image", str(locked))


# ---------------------------------------------------------------- for real, as a user who may not read


@pytest.fixture()
def shared() -> Iterator[Path]:
    """A folder an unprivileged user can enter (pytest's own are root's alone), removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="robofailring-permissions-") as folder:
        os.chmod(folder, 0o777)
        yield Path(folder)


def as_unprivileged(work: Path, *args: object) -> subprocess.CompletedProcess[str]:
    """The `robofailring` command without the power to read what it may not (as root: still root, so the
    checkout stays readable wherever it lies, e.g. under a 0700 temporary folder, but with every capability
    dropped, so a file's mode bits hold for it as for any user); as another user, as that user."""
    source = {str(Path(module.__file__).parents[1]) for module in (robofailring, rfr_viz)}  # type: ignore[arg-type]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(sorted(source)),
        "HOME": str(work),
        "ROBOFAILRING_PROGRESS": "0",
    }
    command = [sys.executable, "-c", "from rfr_viz.cli.app import app; app()", *map(str, args)]
    if os.geteuid() == 0:  # no capability survives the exec: CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH gone
        command = ["setpriv", "--bounding-set=-all", "--inh-caps=-all", "--ambient-caps=-all", *command]
    return subprocess.run(command, capture_output=True, text=True, env=env, check=False)


@pytest.fixture()
def unprivileged(shared: Path) -> Path:
    """`shared` once the command is known to start as the unprivileged user: else `missing` says why (a
    failure in the full lane, where these are the only tests that see a real EACCES)."""
    if os.geteuid() == 0 and shutil.which("setpriv") is None:
        missing(
            "running as root, and no setpriv to run the command without root's capabilities: "
            "apt-get install -y --no-install-recommends util-linux"
        )
    probe = as_unprivileged(shared, "--help")
    if probe.returncode != 0:
        missing(f"the robofailring command does not start as an unprivileged user: {probe.stderr[-300:]}")
    return shared


def one_error(run: subprocess.CompletedProcess[str], status: int) -> str:
    assert run.returncode == status, run.stdout + run.stderr
    errors = [line for line in run.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "Traceback" not in run.stderr, run.stderr
    return errors[0]


def test_a_frame_or_folder_of_mode_000_is_status_1_naming_it(unprivileged: Path, cache: list[str]) -> None:
    data = write_aha_dataset(
        unprivileged / "data", symbols=("grasp_wp2", "wrong_object"), episodes=1, length=3
    )
    work = unprivileged / "work"
    work.mkdir(mode=0o777)
    work.chmod(0o777)
    memory = work / "memory"
    assert cli("build-memory", data, "--out", memory, *cache).exit_code == 0
    locked = data / EPISODE / "front_1.png"
    locked.chmod(0o000)
    error = one_error(as_unprivileged(work, "detect", data / EPISODE, "--memory", memory), 1)
    assert "cannot read image" in error and str(locked) in error, error
    locked.chmod(0o644)
    folder = data / "pick_cube_wrong_object_episode0"
    folder.chmod(0o000)
    try:
        run = as_unprivileged(
            work, "build-memory", data, "--out", work / "again", "--cache-dir", work / "cache"
        )
    finally:
        folder.chmod(0o755)
    error = one_error(run, 1)
    assert f"cannot read folder {folder}: permission denied" in error, (
        error
    )  # was "cannot write …/metadata.yaml"
    assert not (work / "again").exists()


def test_a_permission_error_that_says_neither_read_nor_write_is_worded_as_neither() -> None:
    """describe() words an EACCES as it is: the error does not say whether a read or a write failed."""
    import errno as codes

    from robofailring.errors import describe

    said = describe(PermissionError(codes.EACCES, "Permission denied", "/data/run_1"))
    assert said == "no permission to use /data/run_1; give this user access to it, or choose another path"
    assert describe(OSError(codes.EROFS, "Read-only file system", "/ro")).startswith("cannot write /ro")
