"""Progress where stderr is a log, not a terminal (issue 50): whole lines, at most one per `LOG_EVERY_S` and
one at the end, never the `\\r` redraws of a bar that a log keeps as one ever-growing line."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import pytest
from synthetic import write_project_dataset

from robofailring import progress
from robofailring.progress import LineProgress, progress_bar

MAIN = "import sys; from rfr_viz.cli.app import main; sys.argv[1:] = sys.argv[2:]; sys.exit(main())"


def test_a_verb_logged_to_a_file_writes_progress_as_lines_without_carriage_returns(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2)
    env = {key: value for key, value in os.environ.items() if key != "ROBOFAILRING_PROGRESS"}
    log = tmp_path / "log.txt"
    with log.open("wb") as stderr:  # a file: not a terminal
        command = [sys.executable, "-c", MAIN, "-", "build-memory", str(data), "--out", str(tmp_path / "m")]
        done = subprocess.run(
            [*command, "--cache-dir", str(tmp_path / "c")], stderr=stderr, env=env, check=False
        )
    assert done.returncode == 0
    written = log.read_bytes()
    assert b"\r" not in written and b"\x1b[" not in written  # no redraws, no cursor movements
    lines = written.decode().splitlines()
    (encoded,) = [line for line in lines if line.startswith("encoding memory: ")]
    count = encoded.split()[2].split("/")
    assert count[0] == count[1] and encoded.endswith("frame (100 %)")  # the one line at the end


def test_line_progress_says_a_line_at_most_every_interval_and_at_the_end(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    stream = io.StringIO()
    with LineProgress(total=4, desc="triage", unit="episode", stream=stream) as bar:
        for _ in range(3):
            bar.update(1)  # within the interval: nothing said
        assert stream.getvalue() == ""
        monkeypatch.setattr(progress, "LOG_EVERY_S", 0.0)
        bar.update(1)
    assert stream.getvalue() == "triage: 4/4 episode (100 %)\ntriage: 4/4 episode (100 %)\n"
    monkeypatch.setenv("ROBOFAILRING_PROGRESS", "0")
    assert progress_bar(total=3, desc="x").disable  # silenced: a disabled tqdm bar
    monkeypatch.setenv("ROBOFAILRING_PROGRESS", "1")
    assert not isinstance(progress_bar(total=3, desc="x"), LineProgress)  # forced: the bar
