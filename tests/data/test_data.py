"""Loaders: numeric frame order, the three layouts, auto-detection and clear errors."""

from __future__ import annotations

import json
from decimal import Decimal
from pathlib import Path

import pytest
from environment import shared_data
from synthetic import write_episode, write_project_dataset

from robofailring import Outcome, load_dataset, load_trajectory
from robofailring.data.images import write_png
from robofailring.data.layouts import LAYOUTS_HELP, parse_aha_name
from robofailring.data.layouts.folders import frame_number
from robofailring.errors import DataError


def test_numeric_order() -> None:
    names = [Path(f"{i}.png") for i in (10, 9, 1, 0, 100, 2)]
    assert [p.stem for p in sorted(names, key=lambda p: frame_number(p.stem))] == [
        "0",
        "1",
        "2",
        "9",
        "10",
        "100",
    ]
    views = [Path(f"front_{i}.png") for i in (11, 2, 1)]
    assert [p.stem for p in sorted(views, key=lambda p: frame_number(p.stem))] == [
        "front_1",
        "front_2",
        "front_11",
    ]
    stamps = [Path(f"{s}.png") for s in ("1700000001.1", "1700000000.8", "1700000000.85")]
    assert [frame_number(p.stem) for p in sorted(stamps, key=lambda p: frame_number(p.stem))] == [
        Decimal("1700000000.8"), Decimal("1700000000.85"), Decimal("1700000001.1"),
    ]  # fmt: skip
    assert frame_number("frame") is None


@pytest.mark.parametrize(
    ("name", "parsed"),
    [
        ("take_lid_off_saucepan_rotation_x_wp1_episode0", ("take_lid_off_saucepan", "rotation_x_wp1", "0")),
        ("put_rubbish_in_bin_no_rotation_wp2_episode12", ("put_rubbish_in_bin", "no_rotation_wp2", "12")),
        ("basketball_in_hoop_wrong_object_episode3", ("basketball_in_hoop", "wrong_object", "3")),
        ("open_microwave_translation_z_wp4_episode1", ("open_microwave", "translation_z_wp4", "1")),
        ("slide_block_to_target_grasp_wp2_episode5", ("slide_block_to_target", "grasp_wp2", "5")),
        ("pick_cube_success_episode4", ("pick_cube", None, "4")),
        ("not_a_failure_folder", None),
    ],
)
def test_aha_names_parse_from_the_right(name: str, parsed: tuple[str, str | None, str] | None) -> None:
    assert parse_aha_name(name) == parsed


def test_aha_layout(aha_dataset: Path) -> None:
    dataset = load_dataset(aha_dataset)
    assert dataset.layout == "aha"
    trajectories = list(dataset)
    assert len(trajectories) == 2 * 3 * 2
    first = trajectories[0]
    assert first.outcome is Outcome.FAILURE and first.symbol is not None
    assert sorted(first.views) == ["front", "overhead", "wrist"]
    assert [f.path.name for f in first.views["front"]] == [f"front_{i}.png" for i in range(6)]
    assert {t.task for t in trajectories} == {"pick_cube", "push_cube"}


def test_maniskill_layout(tmp_path: Path) -> None:
    views = ("front", "side", "wrist")
    write_episode(
        tmp_path / "FailPickCube-v1" / "3" / "Ground_Truth", "pick_cube", None, length=12, views=views
    )
    write_episode(
        tmp_path / "FailPickCube-v1" / "3" / "0_trans_x_stage2", "pick_cube", "grasp", length=11, views=views
    )
    write_episode(
        tmp_path / "FailPickCube-v1" / "10" / "1_grasp_1", "pick_cube", "grasp", length=4, views=views
    )
    dataset = load_dataset(tmp_path)
    assert dataset.layout == "maniskill"
    trajectories = {t.episode: t for t in dataset}
    assert set(trajectories) == {"3/Ground_Truth", "3/0_trans_x_stage2", "10/1_grasp_1"}
    success = trajectories["3/Ground_Truth"]
    assert success.outcome is Outcome.SUCCESS and success.symbol is None and success.task == "FailPickCube-v1"
    failure = trajectories["3/0_trans_x_stage2"]
    assert failure.symbol == "trans_x_stage2" and failure.outcome is Outcome.FAILURE
    assert [f.path.name for f in failure.views["side"]][-2:] == ["9.png", "10.png"]
    # a single episode folder of this layout knows its task from the path
    single = load_trajectory(tmp_path / "FailPickCube-v1" / "3" / "0_trans_x_stage2")
    assert single.task == "FailPickCube-v1" and single.symbol == "trans_x_stage2"


def test_project_layout_manifest(tmp_path: Path) -> None:
    write_episode(tmp_path / "pick_cube_slip_wp3_episode1", "pick_cube", "slip_wp3", layout="aha")
    write_episode(tmp_path / "pick_cube_success_episode2", "pick_cube", None, layout="aha")
    manifest = {
        "format": "robofailring-dataset",
        "format_version": 1,
        "fps": 10,
        "episodes": [
            {
                "dir": "pick_cube_slip_wp3_episode1",
                "task": "pick_cube",
                "label": "slip_wp3",
                "outcome": "failure",
                "split": "test",
                "views": ["front", "overhead", "wrist"],
            },
            {
                "dir": "pick_cube_success_episode2",
                "task": "pick_cube",
                "label": None,
                "outcome": "success",
                "split": "train",
            },
        ],
    }
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    dataset = load_dataset(tmp_path)
    assert dataset.layout == "project"
    slip, success = list(dataset)
    assert (slip.symbol, slip.outcome, slip.split, slip.fps) == ("slip_wp3", Outcome.FAILURE, "test", 10)
    assert success.outcome is Outcome.SUCCESS and success.split == "train"
    assert [t.episode for t in dataset.select(split="train")] == ["pick_cube_success_episode2"]
    # an episode folder inside a project dataset takes its labels from the manifest
    assert load_trajectory(tmp_path / "pick_cube_slip_wp3_episode1").split == "test"
    (tmp_path / "pick_cube_success_episode2" / "front_0.png").unlink()
    manifest["episodes"].append({"dir": "gone", "task": "pick_cube", "outcome": "success"})
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DataError, match="gone"):
        list(load_dataset(tmp_path))


def test_project_layout_reads_a_failures_onset_frame(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2, length=6)
    manifest = json.loads((data / "manifest.json").read_text())
    by_dir = {record["dir"]: record for record in manifest["episodes"]}
    by_dir["pick_cube_slip_wp3_episode0"]["onset_frame"] = 3
    by_dir["pick_cube_success_episode0"]["onset_frame"] = None
    (data / "manifest.json").write_text(json.dumps(manifest))
    onsets = {t.episode: t.onset_frame for t in load_dataset(data)}
    assert onsets["pick_cube_slip_wp3_episode0"] == 3
    # a manifest written before onsets (no key) and every success: unknown
    assert onsets["pick_cube_grasp_wp2_episode0"] is None and onsets["pick_cube_success_episode0"] is None
    for bad, phrase in (
        (6, "not a frame of the trajectory (its 6 frames are 0 to 5)"),
        (-1, "is negative"),
        (1.5, "not an integer"),
        ("soon", "not an integer"),
        (True, "not an integer"),
    ):
        by_dir["pick_cube_slip_wp3_episode0"]["onset_frame"] = bad
        (data / "manifest.json").write_text(json.dumps(manifest))
        with pytest.raises(DataError) as error:
            list(load_dataset(data))
        assert str(data / "manifest.json") in str(error.value) and "pick_cube_slip_wp3_episode0" in str(
            error.value
        )
        assert phrase in str(error.value) and repr(bad) in str(error.value)


def test_a_labels_files_onset_frame_wins_and_is_checked_against_the_episode(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2, length=6)
    labels = tmp_path / "labels.csv"
    header = "episode,outcome,symbol,onset_frame\n"
    labels.write_text(
        header + "pick_cube_slip_wp3_episode0,failure,slip_wp3,4\npick_cube_success_episode1,success,,\n"
    )
    onsets = {t.episode: t.onset_frame for t in load_dataset(data, labels=labels)}
    assert onsets["pick_cube_slip_wp3_episode0"] == 4 and onsets["pick_cube_success_episode1"] is None
    labels.write_text(header + "pick_cube_slip_wp3_episode0,failure,slip_wp3,6\n")
    with pytest.raises(DataError) as error:
        load_dataset(data, labels=labels)
    assert str(error.value) == (
        f"{labels} row 1 (episode pick_cube_slip_wp3_episode0): onset_frame 6 is not a frame of the "
        "trajectory (its 6 frames are 0 to 5)"
    )
    for bad, phrase in (("-2", "is negative"), ("2.5", "is not an integer"), ("x", "is not an integer")):
        labels.write_text(header + f"pick_cube_slip_wp3_episode0,failure,slip_wp3,{bad}\n")
        with pytest.raises(DataError, match=f"{labels} row 1: onset_frame '{bad}' {phrase}"):
            load_dataset(data, labels=labels)
    labels.write_text(header + "pick_cube_success_episode1,success,,2\n")
    with pytest.raises(DataError, match="row 1: onset_frame '2' given for a success"):
        load_dataset(data, labels=labels)


def test_a_labels_files_split_column_gives_image_episodes_their_splits(tmp_path: Path) -> None:
    data = tmp_path / "runs"
    for name in ("run_a", "run_b", "run_c", "run_d"):
        write_episode(data / name, "pick_cube", None, length=4)
    labels = tmp_path / "labels.csv"
    labels.write_text(
        "episode,task,outcome,symbol,onset_frame, Split\n"
        "run_a,pick_cube,success,,,train\nrun_b,pick_cube,failure,slip_wp3,2,test\n"
        "run_c,pick_cube,success,,,ood\nrun_d,pick_cube,success,,,\n"
    )
    dataset = load_dataset(data, labels=labels)
    splits = {t.episode: t.split for t in dataset.trajectories()}
    assert splits == {"run_a": "train", "run_b": "test", "run_c": "ood", "run_d": None}
    assert [t.episode for t in dataset.select(split="ood")] == ["run_c"]


def test_unknown_layout_names_the_expected_ones(tmp_path: Path) -> None:
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "readme.txt").write_text("hello")
    with pytest.raises(DataError) as error:
        load_dataset(tmp_path)
    assert str(tmp_path) in str(error.value) and LAYOUTS_HELP in str(error.value)
    with pytest.raises(DataError, match="is not a directory"):
        load_dataset(tmp_path / "missing")


def test_unreadable_image_names_the_file(tmp_path: Path) -> None:
    folder = write_episode(tmp_path / "ep", "pick_cube", None, length=3)
    (folder / "front" / "1.png").write_bytes(b"\x89PNG truncated")
    trajectory = load_trajectory(folder, task="pick_cube")
    with pytest.raises(DataError, match=r"front/1\.png"):
        trajectory.views["front"][1].load()


def test_episode_without_task_asks_for_it(tmp_path: Path) -> None:
    folder = tmp_path / "episode"
    folder.mkdir()
    write_png(folder / "front_0.png", __import__("numpy").zeros((8, 8, 3), "uint8"))
    with pytest.raises(DataError, match="--task"):
        load_trajectory(folder)


def test_real_maniskill_episode() -> None:
    trajectory = load_trajectory(shared_data("maniskill-failgen-episode"), task="FailPickCube-v1")
    assert trajectory.view_names == ["front", "side", "wrist"]
    assert trajectory.length == 69
    assert trajectory.views["side"][-1].path.name == "68.png"
    image = trajectory.views["wrist"][10].load()
    assert image.shape == (256, 256, 3) and image.dtype.name == "uint8"


def test_aha_episodes_grouped_per_task_and_with_view_folders(tmp_path: Path) -> None:
    """Real exports nest episodes one level down and may keep one sub-folder per view."""
    write_episode(
        tmp_path / "pick_cube" / "pick_cube_grasp_wp2_episode10", "pick_cube", "grasp_wp2", layout="aha"
    )
    write_episode(
        tmp_path / "pick_cube" / "pick_cube_grasp_wp2_episode2", "pick_cube", "grasp_wp2", layout="aha"
    )
    write_episode(
        tmp_path / "open_drawer" / "open_drawer_wrong_object_episode0",
        "open_drawer",
        "wrong_object",
        length=4,
    )
    (tmp_path / "open_drawer" / "notes").mkdir()  # a stray folder is not an episode
    dataset = load_dataset(tmp_path)
    assert dataset.layout == "aha"
    trajectories = list(dataset)
    assert [t.episode for t in trajectories] == [
        "open_drawer/open_drawer_wrong_object_episode0",
        "pick_cube/pick_cube_grasp_wp2_episode2",
        "pick_cube/pick_cube_grasp_wp2_episode10",
    ]
    subfolders = trajectories[0]
    assert subfolders.task == "open_drawer" and subfolders.symbol == "wrong_object"
    assert subfolders.view_names == ["front", "overhead", "wrist"] and subfolders.length == 4
    assert [f.path.name for f in subfolders.views["wrist"]] == [f"{i}.png" for i in range(4)]


@pytest.mark.parametrize("depth", ["task", "seed"])
def test_maniskill_root_may_be_one_task_or_one_seed(tmp_path: Path, depth: str) -> None:
    views = ("front", "side", "wrist")
    task_dir = tmp_path / "FailStackCube-v1"
    write_episode(task_dir / "7" / "Ground_Truth", "stack_cube", None, length=5, views=views)
    write_episode(task_dir / "7" / "2_rot_z_3", "stack_cube", "rot_z_3", length=5, views=views)
    root = task_dir if depth == "task" else task_dir / "7"
    dataset = load_dataset(root)
    assert dataset.layout == "maniskill"
    found = {t.episode: t for t in dataset}
    assert set(found) == {"7/Ground_Truth", "7/2_rot_z_3"}
    assert {t.task for t in found.values()} == {"FailStackCube-v1"}
    assert found["7/2_rot_z_3"].symbol == "rot_z_3" and found["7/Ground_Truth"].outcome is Outcome.SUCCESS
