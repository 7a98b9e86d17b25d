"""Said, not silent: `detect` and `replay` on one of the memory's own episodes warn once and say `in_memory`."""

from __future__ import annotations

import json
from pathlib import Path

from fault_helpers import cli
from rrd import properties
from synthetic import write_episode

OWN = "pick_cube_grasp_wp2_episode0"  # an episode of the `data` fixture, so of the memory built from it


def warnings(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("warning:")]


def test_detect_on_an_own_episode_warns_once_and_says_in_memory(
    data: Path, memory: Path, cache: list[str]
) -> None:
    result = cli("detect", data / OWN, "--memory", memory, "--json", *cache)
    assert result.exit_code == 0, result.output
    found = json.loads(result.stdout)
    assert found["in_memory"] is True
    assert max(found["views"]["front"]["similarity"]) == 1.0  # the self-match the warning is about
    said = warnings(result.stderr)
    assert len(said) == 1, result.stderr
    assert f"pick_cube/{OWN}" in said[0] and "--leave-one-out" in said[0]


def test_detect_with_leave_one_out_does_not_warn(data: Path, memory: Path, cache: list[str]) -> None:
    result = cli("detect", data / OWN, "--memory", memory, "--json", "--leave-one-out", *cache)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["in_memory"] is False
    assert warnings(result.stderr) == []


def test_a_new_episode_named_like_an_own_one_does_not_warn(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    """Frames decide, not names: a new dataset reuses episode names."""
    episode = write_episode(tmp_path / "new" / OWN, "pick_cube", "grasp_wp2", length=3, layout="aha", shift=2)
    result = cli("detect", episode, "--memory", memory, "--json", *cache)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["in_memory"] is False
    assert warnings(result.stderr) == []


def test_replay_of_an_own_episode_warns_and_its_recording_says_so(
    data: Path, memory: Path, cache: list[str], tmp_path: Path
) -> None:
    out = tmp_path / "recordings"
    result = cli("replay", data, "--memory", memory, "--out", out, "--trajectory", f"pick_cube/{OWN}", *cache)
    assert result.exit_code == 0, result.output
    said = warnings(result.stderr)
    assert len(said) == 1 and f"pick_cube/{OWN}" in said[0], result.stderr
    assert properties(out / f"pick_cube__{OWN}.rrd")["in_memory"] is True

    held_out = cli(
        "replay", data, "--memory", memory, "--out", out, "--trajectory", f"pick_cube/{OWN}",
        "--leave-one-out", *cache,
    )  # fmt: skip
    assert held_out.exit_code == 0, held_out.output
    assert warnings(held_out.stderr) == []
    assert properties(out / f"pick_cube__{OWN}.rrd")["in_memory"] is False
