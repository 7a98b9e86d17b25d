"""Every verb that writes an output folder holds its lock for the whole job (issue 24).

A second process holds the lock, as a concurrent run would; the verb under test must refuse with
one `error:` line naming the busy output, exit status 1, and write nothing into the folder.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from fault_helpers import cli, refused, tree
from synthetic import write_project_dataset

_HOLD = (
    "import sys; from robofailring.atomic import output_lock\n"
    "with output_lock(sys.argv[1]):\n    print('held', flush=True); sys.stdin.read()"
)


@pytest.fixture()
def busy(tmp_path: Path) -> Iterator[Path]:
    """An output folder (with one file of an earlier run) whose lock another live process holds."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "evaluation.md").write_text("an earlier run")
    holder = subprocess.Popen(
        [sys.executable, "-c", _HOLD, str(out)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        yield out
    finally:
        holder.kill()
        holder.wait()


def _untouched(out: Path) -> None:
    assert tree(out) == {"evaluation.md": b"an earlier run"}
    assert sorted(p.name for p in out.iterdir()) == ["evaluation.md"]


def test_a_second_evaluate_into_a_busy_out_is_refused_and_writes_nothing(
    busy: Path, cache: list[str], tmp_path: Path
) -> None:
    project = write_project_dataset(
        tmp_path / "project", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=3
    )
    command = [
        sys.executable,
        "-c",
        "import sys; from rfr_viz.cli.app import app; app(sys.argv[1:])",
        "evaluate",
        str(project),
        "--out",
        str(busy),
        *cache,
    ]
    env = {**os.environ, "ROBOFAILRING_PROGRESS": "0"}
    second = subprocess.run(command, capture_output=True, text=True, env=env, check=False, timeout=300)
    assert second.returncode == 1, second.stderr
    errors = [line for line in second.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "Traceback" not in second.stderr, second.stderr
    assert "another robofailring process is writing" in errors[0] and str(busy) in errors[0]
    _untouched(busy)


def test_review_compare_encoders_and_demo_refuse_a_busy_out(
    busy: Path, memory: Path, data: Path, cache: list[str], tmp_path: Path
) -> None:
    evaluation = tmp_path / "evaluation.json"
    evaluation.write_text(
        json.dumps({"false_alarms": [], "misses": [], "operating_delta": 0.5, "k": 1, "memory": str(memory)})
    )
    verbs = [
        ("review", evaluation, "--data", data, "--out", busy, *cache),
        ("compare-encoders", data, "--encoder", "pixels", "--encoder", "pixels:16", "--out", busy, *cache),
        ("demo", "--out", busy, "--data-dir", tmp_path / "sim", *cache),
    ]
    for verb in verbs:
        refused(cli(*verb), 1, "another robofailring process is writing", str(busy))
        _untouched(busy)
    assert not (tmp_path / "sim").exists()  # refused before anything was simulated
