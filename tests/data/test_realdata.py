"""Real data as people have it: any waypoint, nothing dropped silently, ambiguous frame names."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from synthetic import synthetic_frame, write_episode
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring import load_dataset, load_trajectory
from robofailring.data.images import write_png
from robofailring.errors import DataError

# The names of a public real-robot failure set in the AHA layout (one `front` view, 3–8 keyframes).
REAL_NAMES = (
    "cook_carrot_wrong_sequence_wp4_episode1",
    "cook_carrot_wrong_sequence_wp2_episode0",
    "apple_in_bowl_wrong_sequence_wp0_episode1",
    "apple_in_bowl_grasp_wp1_episode0",
    "boil_pot_wrong_object_wp4_episode0",
    "boil_pot_slip_wp3_episode2",
    "stack_cups_wrong_object_wp2_episode0",
    "stack_cups_rotation_z_wp0_episode1",
    "open_drawer_wrong_object_wp1_episode3",
    "open_drawer_translation_x_wp6_episode0",
    "wipe_table_wrong_object_wp0_episode0",
    "wipe_table_no_rotation_wp2_episode1",
    "fold_towel_grasp_wp0_episode0",
    "fold_towel_wrong_sequence_wp5_episode2",
    "pour_water_slip_wp1_episode4",
)
# Why a folder under an AHA-layout root that is not named like an episode was not read.
NOT_AN_EPISODE_NAME = (
    "name is not <task>_<failtype>_wp<k>_episode<e>, <task>_wrong_object[_wp<k>]_episode<e> "
    "or <task>_success_episode<e>"
)


def write_real_set(root: Path) -> Path:
    for number, name in enumerate(REAL_NAMES):
        folder = root / name
        folder.mkdir(parents=True)
        frames = 3 + number % 6  # 3..8 keyframes
        for t in range(frames):
            write_png(
                folder / f"front_{t}.png", synthetic_frame("pick_cube", name, 0, t + number, frames + 15)
            )
    return root


def test_the_real_set_builds_fifteen_entries_and_detects_without_task(tmp_path: Path) -> None:
    root = write_real_set(tmp_path / "real")
    dataset = load_dataset(root)
    assert dataset.layout == "aha" and dataset.skipped == []
    by_episode = {t.episode: t for t in dataset}
    assert by_episode["boil_pot_wrong_object_wp4_episode0"].symbol == "wrong_object_wp4"
    assert by_episode["apple_in_bowl_wrong_sequence_wp0_episode1"].task == "apple_in_bowl"
    runner = CliRunner()
    memory = tmp_path / "memory"
    built = runner.invoke(
        app,
        [
            "build-memory",
            str(root),
            "--out",
            str(memory),
            "--failure-frames",
            "end",
            "--cache-dir",
            str(tmp_path / "c"),
        ],
    )
    assert built.exit_code == 0, built.output
    assert (
        "15 entries" in built.output
    )  # the paper's memory: one per failure view and "from 15 failure trajectories over 8 tasks" in built.output
    assert "skipped" not in built.output
    entries = [json.loads(line) for line in (memory / "entries.jsonl").read_text().splitlines()]
    assert sorted(e["episode"] for e in entries) == sorted(REAL_NAMES)
    detected = runner.invoke(
        app,
        [
            "detect",
            str(root / "stack_cups_wrong_object_wp2_episode0"),
            "--memory",
            str(memory),
            "--json",
            "--cache-dir",
            str(tmp_path / "c"),
        ],
    )
    assert detected.exit_code == 0, detected.output
    trace = json.loads(detected.stdout)
    assert (
        trace["task"] == "stack_cups"
        and trace["length"] == 3 + REAL_NAMES.index("stack_cups_wrong_object_wp2_episode0") % 6
    )
    assert trace["views"]["front"]["top_neighbor"][-1]["episode"] == "stack_cups_wrong_object_wp2_episode0"


def test_nothing_under_a_root_is_dropped_silently(tmp_path: Path, aha_dataset: Path) -> None:
    root = tmp_path / "data"
    write_episode(root / "pick_cube_grasp_wp2_episode0", "pick_cube", "grasp_wp2", layout="aha")
    write_episode(root / "pick_cube_slip_wp1_episode1", "pick_cube", "slip_wp1", layout="aha")
    (root / "notes").mkdir()
    (root / "README.txt").write_text("exported by hand")
    write_episode(root / "pick_cube_twist_wp1_episode2", "pick_cube", None, layout="aha")  # unknown type
    (root / "pick_cube_grasp_wp3_episode3").mkdir()  # an episode name, but nothing inside
    (root / "pick_cube_slip_wp1_episode1" / "log.json").write_text("{}")
    dataset = load_dataset(root)
    assert [t.episode for t in dataset] == ["pick_cube_grasp_wp2_episode0", "pick_cube_slip_wp1_episode1"]
    reasons = {item.path.name: item.reason for item in dataset.skipped}
    assert set(reasons) == {
        "notes",
        "README.txt",
        "pick_cube_twist_wp1_episode2",
        "pick_cube_grasp_wp3_episode3",
        "log.json",
    }
    assert "unknown failure type 'twist'" in reasons["pick_cube_twist_wp1_episode2"]
    assert "no images" in reasons["pick_cube_grasp_wp3_episode3"]
    # the CLI: one summary line and the first names; status 3, done but inputs were skipped
    runner = CliRunner()
    result = runner.invoke(
        app, ["build-memory", str(root), "--out", str(tmp_path / "m"), "--cache-dir", str(tmp_path / "c")]
    )
    assert result.exit_code == 3, result.output
    assert "5 folder(s)/file(s) under the data were not read" in result.output
    assert "pick_cube_twist_wp1_episode2: unknown failure type 'twist'" in result.output
    manifest = json.loads((tmp_path / "m" / "manifest.json").read_text())
    assert len(manifest["skipped_inputs"]) == 5
    # and detect on the unknown-type folder names the token instead of asking for --task
    result = runner.invoke(
        app, ["detect", str(root / "pick_cube_twist_wp1_episode2"), "--memory", str(tmp_path / "m")]
    )
    assert result.exit_code == 2 and "unknown failure type 'twist'" in result.output


def test_frames_without_a_number_are_reported_and_counted(tmp_path: Path) -> None:
    root = tmp_path / "data"
    write_episode(
        root / "pick_cube_grasp_wp2_episode0", "pick_cube", "grasp_wp2", layout="aha", views=("wrist",)
    )
    episode = root / "pick_cube_slip_wp1_episode1"
    write_episode(episode, "pick_cube", "slip_wp1", layout="aha", views=("wrist",))
    for letter in "abcd":
        write_png(episode / f"front_{letter}.png", np.zeros((8, 8, 3), np.uint8))
    dataset = load_dataset(root)
    (skipped,) = dataset.skipped
    assert (
        skipped.path == episode
        and "4 image(s) without a frame number (front_a.png, front_b.png, front_c.png, …)" in skipped.reason
    )
    slip = next(t for t in dataset if t.episode == episode.name)
    assert slip.view_names == ["wrist"] and slip.skipped == (skipped,)
    runner = CliRunner()
    result = runner.invoke(
        app, ["build-memory", str(root), "--out", str(tmp_path / "m"), "--cache-dir", str(tmp_path / "c")]
    )
    assert result.exit_code == 3, result.output
    assert "0 views skipped" not in result.output
    assert "skipped: 0 view(s) with < 2 frames, 1 folder(s)/file(s) not read" in result.output
    assert "without a frame number" in result.output
    # one episode folder: detect says it too, and --json carries it
    result = runner.invoke(
        app,
        [
            "detect",
            str(episode),
            "--memory",
            str(tmp_path / "m"),
            "--json",
            "--cache-dir",
            str(tmp_path / "c"),
        ],
    )
    assert result.exit_code == 3, result.output  # done, but some inputs were skipped
    assert json.loads(result.stdout)["skipped_inputs"] == [skipped.to_dict()]
    assert "without a frame number" in result.stderr


@pytest.mark.parametrize("layout", ["aha", "subfolders"])
def test_two_files_with_one_frame_number_are_an_error_naming_both(tmp_path: Path, layout: str) -> None:
    episode = write_episode(
        tmp_path / "pick_cube_grasp_wp2_episode0", "pick_cube", "grasp_wp2", layout=layout
    )
    image = np.full((8, 8, 3), 9, np.uint8)
    if layout == "aha":
        write_png(episode / "front_01.png", image)
        names = ("front_1.png", "front_01.png")
    else:
        write_png(episode / "front" / "01.png", image)
        names = ("1.png", "01.png")
    with pytest.raises(DataError) as error:
        load_trajectory(episode, task="pick_cube")
    message = str(error.value)
    assert all(name in message for name in names) and "two frames numbered 1" in message
    with pytest.raises(DataError, match="front_01.png" if layout == "aha" else "01.png"):
        load_dataset(tmp_path)


def test_maniskill_stray_folders_are_reported(tmp_path: Path) -> None:
    views = ("front", "side", "wrist")
    write_episode(
        tmp_path / "FailPickCube-v1" / "3" / "Ground_Truth", "pick_cube", None, length=4, views=views
    )
    write_episode(
        tmp_path / "FailPickCube-v1" / "3" / "0_twist_x_2", "pick_cube", "grasp", length=4, views=views
    )
    dataset = load_dataset(tmp_path)
    assert [t.episode for t in dataset] == ["3/Ground_Truth"]
    (skipped,) = dataset.skipped
    assert skipped.path.name == "0_twist_x_2" and "not a ManiSkill-failgen episode folder" in skipped.reason


def test_evaluate_with_a_stride_reports_original_frames_and_what_was_not_read(tmp_path: Path) -> None:
    root = tmp_path / "data"
    for episode in range(4):
        for symbol in ("grasp_wp2", "slip_wp1"):
            write_episode(
                root / f"pick_cube_{symbol}_episode{episode}",
                "pick_cube",
                symbol,
                layout="aha",
                length=9,
                shift=episode,
            )
        write_episode(root / f"pick_cube_success_episode{episode}", "pick_cube", None, layout="aha", length=9)
    (root / "stray").mkdir()
    runner = CliRunner()
    out = tmp_path / "eval"
    result = runner.invoke(
        app,
        [
            "evaluate",
            str(root),
            "--out",
            str(out),
            "--stride",
            "3",
            "--target-fpr",
            "0.5",
            "--cache-dir",
            str(tmp_path / "c"),
        ],
    )
    assert result.exit_code == 3, result.output  # done, but some inputs were skipped
    assert "1 folder(s)/file(s) under the data were not read" in result.output
    report = json.loads((out / "evaluation.json").read_text())
    assert report["stride"] == 3
    assert report["skipped_inputs"] == [{"path": str(root / "stray"), "reason": NOT_AN_EPISODE_NAME}]
    detected = [row["t_det"] for row in report["trajectories"] if row["t_det"] is not None]
    assert any(t > 0 for t in detected) and all(t % 3 == 0 for t in detected)  # original frame numbers
    assert {row["length"] for row in report["trajectories"]} == {9}
    assert "stray" in (out / "evaluation.md").read_text()


@pytest.mark.parametrize(
    "verb",
    [
        "build-memory",
        "detect",
        "evaluate",
    ],
)
def test_a_verb_that_skipped_inputs_ends_with_3(verb: str, tmp_path: Path) -> None:
    """Status 3 is "done, but some inputs were skipped" (robofailring.cli.exit_codes), for every verb."""
    root = tmp_path / "data"
    for episode in range(4):  # evaluate's split: even episodes build, odd ones are scored
        for symbol in ("grasp_wp2", None):
            name = f"pick_cube_{symbol or 'success'}_episode{episode}"
            write_episode(root / name, "pick_cube", symbol, layout="aha", length=3, shift=episode)
    runner = CliRunner()
    cache = ["--cache-dir", str(tmp_path / "c")]
    memory = tmp_path / "memory"
    built = runner.invoke(app, ["build-memory", str(root), "--out", str(memory), *cache])
    assert built.exit_code == 0, built.output  # nothing skipped yet: done
    (root / "stray").mkdir()
    episode = root / "pick_cube_grasp_wp2_episode1"
    write_png(episode / "front_a.png", np.zeros((8, 8, 3), np.uint8))  # a frame without a number
    arguments = {
        "build-memory": ["build-memory", str(root), "--out", str(tmp_path / "again")],
        "detect": ["detect", str(episode), "--memory", str(memory), "--json"],
        "evaluate": ["evaluate", str(root), "--out", str(tmp_path / "eval"), "--target-fpr", "0.5"],
    }
    result = runner.invoke(app, [*arguments[verb], *cache])
    assert "without a frame number" in result.output
    assert result.exit_code == 3, result.output
