"""A view of fewer than 2 frames is skipped, listed and ends the command with status 3 in every verb that
scores data (issue 35, item 9: `build-memory` and `calibrate` said 3, `detect` and `replay` said 0)."""

from __future__ import annotations

from pathlib import Path

import pytest
from fault_helpers import cli
from synthetic import write_aha_dataset, write_episode

SHORT = "side"  # a camera that saved one image of each run


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """AHA runs (failures and successes, 3 frames a view), each with a fourth view of one frame."""
    root = write_aha_dataset(
        tmp_path_factory.mktemp("short") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=4,
        length=3,
    )
    for episode in range(4):
        write_episode(root / f"pick_cube_success_episode{episode}", "pick_cube", None, length=3, layout="aha")
    for run in root.iterdir():
        write_episode(run, "pick_cube", None, length=1, views=(SHORT,), layout="aha")
    return root


@pytest.fixture(scope="module")
def built(runs: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    folder = tmp_path_factory.mktemp("short-memory")
    cache = ["--cache-dir", str(folder / "cache")]
    result = cli("build-memory", runs, "--out", folder / "memory", *cache)
    assert result.exit_code == 3, result.output  # the documented case: its failure views of 1 frame
    assert f"view {SHORT}: 1 frame(s)" in result.output
    return folder / "memory", cache


VERBS = ("detect", "calibrate", "replay", "evaluate")


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_lists_a_view_of_one_frame_and_ends_with_status_3(
    verb: str, runs: Path, built: tuple[Path, list[str]], tmp_path: Path
) -> None:
    memory, cache = built
    episode = runs / "pick_cube_success_episode1"
    args: dict[str, list[object]] = {
        "detect": [episode, "--memory", memory],
        "calibrate": [runs, "--memory", memory, "--target-fpr", "0.5"],
        "replay": [runs, "--memory", memory, "--trajectory", episode.name, "--out", tmp_path / "rec"],
        "evaluate": [runs, "--out", tmp_path / "eval", "--target-fpr", "0.5"],
    }
    result = cli(verb, *args[verb], *cache)
    assert result.exit_code == 3, result.output  # detect and replay ended with 0
    assert "error:" not in result.output
    assert f"view {SHORT}: 1 frame(s), fewer than 2: not scored" in result.output, result.output
