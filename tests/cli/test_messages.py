"""What a user reads when things are unusual (issue 45 item 7): each message says what happened, through
the command line where it is met."""

from __future__ import annotations

import csv
import html
import json
import re
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli, refused
from hdf5_writer import write_robomimic
from synthetic import (
    csv_rows,
    write_aha_dataset,
    write_episode,
    write_labelled_runs,
    write_project_dataset,
    write_unlabelled_runs,
)

from robofailring import load_dataset


def test_triage_takes_each_episodes_task_from_the_labels_file(tmp_path: Path) -> None:
    data, labels = write_labelled_runs(tmp_path / "runs", runs=8, length=4)
    rows = csv_rows(labels)
    for number, row in enumerate(rows):  # a folder of two tasks, told only by the labels' task column
        row["task"] = ("pick_cube", "push_cube")[number // 4]
    with labels.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    out = tmp_path / "out"
    result = cli(
        "triage", data, "--labels", labels, "--out", out, "--replays", "0", "--cache-dir", tmp_path / "c"
    )
    assert result.exit_code == 0, result.output
    ranked = {
        row["episode"]: (row["task"], row["reference"], row["outcome"])
        for row in csv_rows(out / "triage.csv")
    }
    assert ranked == {row["episode"]: (row["task"], "successes", row["outcome"]) for row in rows}


def test_triage_of_one_frame_episodes_says_no_run_has_two_frames(tmp_path: Path) -> None:
    data, _ = write_unlabelled_runs(tmp_path / "runs", successes=3, failures=("grasp_wp2",), length=1)
    result = cli(
        "triage", data, "--task", "pick_cube", "--out", tmp_path / "out", "--cache-dir", tmp_path / "c"
    )
    refused(result, 2, f"none of the 4 episode(s) of {data} has a view of at least 2 frames", "1 frame(s)")
    assert "success" not in result.output


def test_a_symlink_loop_is_listed_as_not_read_and_the_real_views_are_scored(
    built_memory: Path, cache: list[str], tmp_path: Path
) -> None:
    episode = write_episode(tmp_path / "pick_cube_grasp_wp2_episode9", "pick_cube", "grasp_wp2", length=3)
    (episode / "front" / "again").symlink_to(".")  # a link back to its own folder
    (episode / "wrist" / "x").symlink_to("y")  # two links that lead to each other
    (episode / "wrist" / "y").symlink_to("x")
    result = cli("detect", episode, "--memory", built_memory, "--json", *cache)
    assert result.exit_code == 3, result.output  # scored, with inputs not read
    assert set(json.loads(result.stdout)["views"]) == {"front", "overhead", "wrist"}
    assert (
        f"{episode / 'front' / 'again'}: a link back to {(episode / 'front').resolve()}, a folder holding it "
        "(a symlink loop): not read"
    ) in result.output
    assert (
        f"{episode / 'wrist' / 'x'}: a symlink loop ({episode / 'wrist' / 'x'} -> y never reaches"
        in result.output
    )


def test_a_damaged_hdf5_file_is_named_with_why_it_cannot_be_read(tmp_path: Path) -> None:
    data = tmp_path / "demos"
    data.mkdir()
    (data / "lift.hdf5").write_bytes(b"not an HDF5 file: a download cut short")
    result = cli("build-memory", data, "--out", tmp_path / "memory")
    refused(result, 2, f"cannot read HDF5 file {data / 'lift.hdf5'}", "file signature not found")

    def frame(demo: int, camera: int, t: int) -> np.ndarray:
        return np.full((8, 8, 3), 10 * demo + camera + t, dtype=np.uint8)

    for name in ("lift", "can"):  # beside two readable files, the damaged one is listed with its reason
        write_robomimic(data / f"{name}_ph.hdf5", frame, demos=1, length=3)
    unread = {s.path.name: s.reason for s in load_dataset(data, task="lift").skipped}
    assert unread["lift.hdf5"].startswith(f"cannot read HDF5 file {data / 'lift.hdf5'}: ")


def test_replay_of_many_skipped_trajectories_lists_the_first_twenty(
    built_memory: Path, cache: list[str], tmp_path: Path
) -> None:
    data = tmp_path / "data"
    for episode in range(30):  # one frame each: nothing to score
        write_episode(data / f"pick_cube_success_episode{episode}", "pick_cube", None, length=1, layout="aha")
    result = cli("replay", data, "--memory", built_memory, "--out", tmp_path / "out", *cache)
    lines = result.output.splitlines()
    listed = [
        line.split("skipped ", 1)[1] for line in lines if "skipped pick_cube/" in line
    ]  # after a progress bar
    assert len(listed) == 20 and listed[0].startswith("pick_cube/pick_cube_success_episode0: trajectory ")
    assert "  … and 10 more" in lines
    assert lines[-1] == "error: no recording written (30 trajectories skipped)"


def test_calibrate_at_a_tiny_target_fpr_says_the_runs_it_needs_in_a_few_digits(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    successes = tmp_path / "successes"
    for episode in range(3):
        write_episode(
            successes / f"pick_cube_success_episode{episode}", "pick_cube", None, length=3, layout="aha"
        )
    result = cli("calibrate", successes, "--memory", memory, "--target-fpr", "1e-300", *cache)
    refused(
        result, 2, "a guaranteed false-positive rate of 1e-300 needs at least 1e+300 success runs", "got 3"
    )
    assert re.search(r"\d{10}", result.output) is None
    calibrated = cli("calibrate", successes, "--memory", memory, "--target-fpr", "0.25", *cache)
    assert calibrated.exit_code == 0, calibrated.output
    assert "on 3 success runs (target FPR 25 %)" in calibrated.output


CAMERA = "<b>wr|ist"  # a view named with HTML and a table's cell separator


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An evaluation's folder: labelled image runs of views `front` and CAMERA, evaluated at α = 0.5."""
    root = tmp_path_factory.mktemp("evaluated")
    data, labels = write_labelled_runs(root / "runs", runs=16, length=5, views=("front", CAMERA))
    out = root / "eval"
    result = cli(
        "evaluate", data, "--labels", labels, "--out", out, "--target-fpr", "0.5", "--cache-dir", root / "c"
    )
    assert result.exit_code == 0, result.output
    return out


def test_names_with_markup_stay_text_in_evaluation_md_and_report_html(evaluated: Path) -> None:
    markdown = (evaluated / "evaluation.md").read_text(encoding="utf-8")
    row = next(line for line in markdown.splitlines() if line.startswith(r"| \<b\>wr\|ist | "))
    assert len(re.split(r"(?<!\\)\|", row)) == 5  # the views table's three cells, the name in one
    assert "<b>" not in markdown
    assert f"<td>{html.escape(CAMERA, quote=False)}</td>" in (evaluated / "report.html").read_text(
        encoding="utf-8"
    )


def test_report_html_names_the_rule_of_each_false_alarm_and_leads_with_the_default(evaluated: Path) -> None:
    rules = json.loads((evaluated / "evaluation.json").read_text())["rules"]
    assert (rules["paper"]["false_alarms"], rules["contrast"]["false_alarms"]) == (["pick_cube/run_00"], [])
    page = (evaluated / "report.html").read_text(encoding="utf-8")
    said = re.findall(
        r"<p>([^<]*(?:<b>[^<]*</b>)?[^<]*) of the (\w+) rule( \(the detector's default\))?", page
    )
    assert [(rule, bool(default)) for _, rule, default in said] == [("contrast", True), ("paper", False)]
    assert said[0][0] == "No false alarm and no miss"
    assert (
        "<b>1 false alarm</b> of the paper rule: pick_cube/run_00. Replay it, paused at the moment: "
        "<code>robofailring review evaluation.json --data DATA --kind false-alarms --score paper</code>"
    ) in page


def test_memory_pointed_at_a_dataset_says_it_is_a_dataset_and_how_to_build_a_memory(tmp_path: Path) -> None:
    """Issue 50: `--memory` given the data (a newcomer's first slip) said "manifest.json lacks 'encoder'"
    of the project's layout; every verb now names it a dataset and says how to build a memory from it."""
    data = write_project_dataset(tmp_path / "sim", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2)
    aha = write_aha_dataset(tmp_path / "aha", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2)
    episode = data / "pick_cube_grasp_wp2_episode1"
    for given, layout in ((data, "project"), (aha, "aha")):
        said = (
            f"{given} is a dataset ({layout} layout), not a memory; build one with `robofailring build-memory"
        )
        for verb in (("detect", episode), ("calibrate", data), ("memory-info",)):
            result = cli(*verb, "--memory", given) if verb[0] != "memory-info" else cli("memory-info", given)
            refused(result, 2, said)
    empty = tmp_path / "empty"
    empty.mkdir()
    refused(cli("memory-info", empty), 2, f"{empty} is not a failure memory: manifest.json is missing")
