"""Calibration's inputs, said and not silent (issue 24): short success runs skipped, no success runs at all."""

from __future__ import annotations

from pathlib import Path

from fault_helpers import cli, refused
from synthetic import write_aha_dataset, write_episode


def test_calibrate_exits_3_and_names_the_short_success_runs_it_skipped(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    successes = tmp_path / "successes"
    for episode in range(3):
        write_episode(
            successes / f"pick_cube_success_episode{episode}", "pick_cube", None, length=3, layout="aha"
        )
    write_episode(successes / "pick_cube_success_episode9", "pick_cube", None, length=1, layout="aha")
    result = cli("calibrate", successes, "--memory", memory, "--target-fpr", "0.5", *cache)
    assert result.exit_code == 3, result.output
    assert "on 3 success runs" in result.output
    assert "skipped: 1 success run(s) with no view of 2+ frames" in result.output
    assert "skipped pick_cube/pick_cube_success_episode9" in result.output
    assert "calibration" in (memory / "manifest.json").read_text()  # the work was done and stored


def test_evaluate_on_data_without_success_runs_says_what_is_missing(cache: list[str], tmp_path: Path) -> None:
    failures = write_aha_dataset(
        tmp_path / "failures", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=4, length=3
    )
    refused(
        cli("evaluate", failures, "--out", tmp_path / "eval", *cache),
        2,
        "no success trajectory",
        str(failures),
        "split 'train'",
        "add success episodes",
    )
