"""The example scripts run as a user would run them (with the weight-free encoder)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from synthetic import write_aha_dataset, write_episode

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


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
        env={"ROBOFAILRING_CACHE": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin"},
    )
    assert result.returncode == 0, result.stderr
    assert "aha layout" in result.stdout and "memory: 9 entries over 1 tasks" in result.stdout
    assert "failure at frame" in result.stdout and "The failure was caused by" in result.stdout
    assert (tmp_path / "memory" / "manifest.json").is_file()
