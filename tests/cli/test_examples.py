"""The example scripts run as a user would run them (with the weight-free encoder)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from rrd import entity_paths, rows
from synthetic import VIEWS, write_aha_dataset, write_episode, write_project_dataset

from rfr_viz.paths import UNSTOPPED, WATCHED
from rfr_viz.viewer.rrd import verify_recording

pytestmark = pytest.mark.slow  # simulation or end-to-end: the full lane only (scripts/test.sh)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
_PYTHONPATH = {key: os.environ[key] for key in ("PYTHONPATH",) if key in os.environ}  # a worktree's code


def test_build_memory_from_aha_example(tmp_path: Path) -> None:
    data = write_aha_dataset(tmp_path / "aha", tasks=("pick_cube",), episodes=1)
    episode = write_episode(tmp_path / "pick_cube_grasp_wp2_episode7", "pick_cube", "grasp_wp2", layout="aha")
    result = subprocess.run(
        [
            sys.executable,
            str(EXAMPLES / "build_memory_from_aha.py"),
            str(data),
            str(episode),
            "--encoder",
            "pixels",
            "--memory",
            str(tmp_path / "memory"),
            "--delta",
            "0.5",
        ],
        capture_output=True,
        text=True,
        check=False,
        env={"ROBOFAILRING_CACHE": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin", **_PYTHONPATH},
    )
    assert result.returncode == 0, result.stderr
    # dense by default: frames 1-5 of each of the 9 failure views (6 frames, no onset known)
    assert "aha layout" in result.stdout and "memory: 45 entries over 1 tasks" in result.stdout
    assert "failure at frame" in result.stdout and "The failure was caused by" in result.stdout
    assert (tmp_path / "memory" / "manifest.json").is_file()


def test_closed_loop_example(tmp_path: Path) -> None:
    """The proactive-stop story at a small size: memory, calibration, both runs, one valid recording."""
    result = subprocess.run(
        [
            sys.executable,
            str(EXAMPLES / "closed_loop_sim.py"),
            *("--episodes", "1", "--image-size", "48", "--frames", "16"),
            *("--data", str(tmp_path / "data"), "--out", str(tmp_path / "out")),
        ],
        capture_output=True,
        text=True,
        check=False,
        env={"ROBOFAILRING_CACHE": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin", **_PYTHONPATH},
    )
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "memory: " in out and "calibrated δ = " in out
    assert ("STOP at frame" in out) != ("no alarm in 16 frames" in out)
    assert "watched run:" in out and "unstopped run: failure (grasp_wp" in out
    recording = tmp_path / "out" / "pick_cube_grasp_seed11.rrd"
    assert f"rerun {recording}" in out
    verify_recording(recording)
    paths = entity_paths(recording)
    for run in (WATCHED, UNSTOPPED):
        assert {run.camera(view) for view in VIEWS} | {run.outcome, run.detector.state} <= paths


def test_compare_encoders_example(tmp_path: Path, tiny_checkpoint: tuple[Path, Path]) -> None:
    config_json, checkpoint = tiny_checkpoint
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=4)
    result = subprocess.run(
        [
            sys.executable,
            str(EXAMPLES / "compare_encoders.py"),
            str(data),
            *("--encoder", "pixels", "--encoder", f"open_clip:{config_json}:{checkpoint}"),
            *("--out", str(tmp_path / "out"), "--target-fpr", "0.5"),
        ],
        capture_output=True,
        text=True,
        check=False,
        env={"ROBOFAILRING_CACHE": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin", "HF_HUB_OFFLINE": "1"},
    )
    assert result.returncode == 0, result.stderr
    rows = [line for line in result.stdout.splitlines() if line.startswith("| ")]
    assert any("pixels" in row for row in rows) and any("`open_clip:" in row for row in rows), result.stdout
    assert len(rows) == 1 + 2 * 3, result.stdout  # the header and one row per encoder and scoring rule


def test_live_robot_example_records_the_stream(tmp_path: Path) -> None:
    """The user's robot loop with the Rerun sink, saved: every step's cameras and S_t up to the stop."""
    saved = tmp_path / "live.rrd"
    result = subprocess.run(
        [
            sys.executable,
            str(EXAMPLES / "live_robot_sim.py"),
            *("--episodes", "1", "--image-size", "48", "--frames", "16"),
            *("--data", str(tmp_path / "data"), "--save", str(saved)),
        ],
        capture_output=True,
        text=True,
        check=False,
        env={
            "ROBOFAILRING_CACHE": str(tmp_path / "cache"),
            "PATH": "/usr/bin:/bin",
            **_PYTHONPATH,
        },
    )
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "memory: " in out and f"rerun {saved}" in out
    assert ("STOP at step" in out) != ("no alarm in 16 steps" in out)
    verify_recording(saved)
    steps = 16
    if "STOP at step" in out:
        steps = int(out.split("STOP at step ")[1].split()[0]) + 1  # the stop step is the last one fed
    for view in VIEWS:
        assert [frame for frame, _ in rows(saved, f"/score/{view}/paper", "Scalars:scalars")] == list(
            range(steps)
        )
        assert [frame for frame, _ in rows(saved, f"/camera/{view}", "EncodedImage:blob")] == list(
            range(steps)
        )
