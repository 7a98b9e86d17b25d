"""Calibration's inputs, said and not silent (issue 24): short success runs skipped, no success runs at all."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fault_helpers import cli, refused
from lerobot_writer import encode_video, scene
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


def test_calibrate_says_how_far_the_test_fpr_can_stray_with_its_runs(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    successes = tmp_path / "successes"
    for episode in range(4):
        write_episode(
            successes / f"pick_cube_success_episode{episode}", "pick_cube", None, length=3, layout="aha"
        )
    result = cli("calibrate", successes, "--memory", memory, "--target-fpr", "0.2", *cache)
    assert result.exit_code == 0, result.output
    # n = 4 at α = 0.2: k = ⌈5 · 0.8⌉ = 4, the realised FPR is Beta(1, 4), quantile q at 1 − (1 − q)^(1/4)
    assert "with 4 calibration runs the test FPR at α = 20 % lies in 1.3–52.7 %" in result.output
    assert "mean 20.0 %" in result.output
    assert "1110 runs would keep the 95 % quantile ≤ 22.0 % (α + 2 points)" in result.output
    stored = json.loads((memory / "manifest.json").read_text())["calibration"]["rules"]["paper"]["fpr_spread"]
    assert stored["successes"] == 4 and stored["levels"] == [0.05, 0.95]
    assert stored["low"] == pytest.approx(1 - 0.95**0.25, abs=1e-6)
    assert stored["high"] == pytest.approx(1 - 0.05**0.25, abs=1e-6)
    assert stored["bound"] == pytest.approx(0.22) and stored["runs_for_bound"] == 1110


def test_calibrate_never_takes_an_unlabelled_run_for_a_success(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    """One rule for every layout (issue 35, item 4): an episode folder or video folder whose name does not
    say the outcome is not a success; all unlabelled: the error image-episode folders give; some: those
    are listed as not used and the rest calibrate."""
    before = (memory / "manifest.json").read_bytes()
    one = write_episode(tmp_path / "run_a", "pick_cube", "grasp_wp2", length=4)  # a failure, unnamed
    videos = tmp_path / "videos"
    for name in ("run_7", "pick_cube_success_episode3", "pick_cube_success_episode4"):
        for c, view in enumerate(("front", "wrist")):
            encode_video(videos / name / f"{view}.mp4", [scene(3, c, t) for t in range(6)], 10, "h264")
    for data in (one, videos / "run_7"):
        refused(
            cli("calibrate", data, "--memory", memory, "--task", "pick_cube", *cache),
            2,
            "needs to know which episodes failed",
            "--labels",
        )
        assert (memory / "manifest.json").read_bytes() == before  # nothing stored from a failure run
    partly = cli(
        "calibrate", videos, "--memory", memory, "--task", "pick_cube", "--target-fpr", "0.5", *cache
    )
    assert partly.exit_code == 3, partly.output
    assert "on 2 success runs" in partly.output
    assert "1 episode(s) without an outcome" in partly.output and "pick_cube/run_7" in partly.output
