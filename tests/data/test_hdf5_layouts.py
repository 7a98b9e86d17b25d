"""robomimic/LIBERO files and ALOHA episode folders written with h5py, read lazily and through every verb."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from hdf5_writer import write_aloha, write_robomimic
from pipeline import invoke, run_pipeline
from synthetic import synthetic_frame

from robofailring import FailureMemory, load_dataset, load_trajectory
from robofailring.data.frame_ref import read_frame
from robofailring.data.hdf5 import HDF5Frame
from robofailring.data.model import Trajectory
from robofailring.data.splits import split_of
from robofailring.errors import DataError

LENGTH = 10
FAILED = {0: "grasp_wp2", 1: "slip_wp1", 4: "grasp_wp2", 5: "slip_wp1"}  # demo -> symbol; others succeed


def frame(demo: int, camera: int, t: int, symbols: dict[int, str] = FAILED) -> np.ndarray:
    return synthetic_frame("pick_cube", symbols.get(demo), camera, t, LENGTH, size=32)


def write_labels(path: Path, symbols: dict[str, str], episodes: list[str], task: str | None = None) -> Path:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "outcome", "symbol", *(["task"] if task else [])])
        for episode in episodes:
            symbol = symbols.get(episode)
            row = [episode, "failure" if symbol else "success", symbol or ""]
            writer.writerow(row + ([task] if task else []))
    return path


@pytest.fixture
def robomimic(tmp_path: Path) -> tuple[Path, Path]:
    path = write_robomimic(
        tmp_path / "lift_ph_image.hdf5",
        frame,
        demos=8,
        length=LENGTH,
        masks={"train": range(4), "valid": range(4, 8)},
    )
    labels = write_labels(
        tmp_path / "labels.csv", {f"demo_{d}": s for d, s in FAILED.items()}, [f"demo_{d}" for d in range(8)]
    )
    return path, labels


def test_a_robomimic_file_reads_lazily_with_its_masks_as_splits(robomimic: tuple[Path, Path]) -> None:
    path, labels = robomimic
    dataset = load_dataset(path, labels=labels)
    assert dataset.layout == "robomimic" and dataset.views == ["agentview", "robot0_eye_in_hand"]
    by_key = {t.episode: t for t in dataset}
    assert list(by_key) == [f"demo_{d}" for d in range(8)]
    demo = by_key["demo_5"]
    assert demo.task == "Lift" and demo.split == "valid" and demo.symbol == "slip_wp1" and demo.fps == 20.0
    assert (
        by_key["demo_2"].split == "train"
        and by_key["demo_2"].outcome is not None
        and not by_key["demo_2"].symbol
    )
    assert demo.length == LENGTH
    source = demo.views["robot0_eye_in_hand"][7].source
    assert isinstance(source, HDF5Frame) and source.reference.endswith(
        "#/data/demo_5/obs/robot0_eye_in_hand_image#frame=7"
    )
    assert np.array_equal(demo.views["robot0_eye_in_hand"][7].load(), frame(5, 1, 7))
    # the low-dimensional obs are not views; --task wins over env_args
    assert load_dataset(path, task="lift the cube").episodes[0].task == "lift the cube"


@pytest.mark.slow  # an end-to-end run of every verb: the full lane
def test_a_robomimic_file_through_every_verb(tmp_path: Path, robomimic: tuple[Path, Path]) -> None:
    path, labels = robomimic
    found = run_pipeline(
        tmp_path, path, trajectory="demo_4", options=["--labels", labels], evaluate=["--test-split", "valid"]
    )
    assert found["info"]["layout"] == "robomimic"
    assert found["info"]["views_read"] == ["agentview", "robot0_eye_in_hand"]
    assert _failure_views_to_their_end(found["memory"]) == 8  # four failures, two views each
    detected = found["detect"]
    assert detected["layout"] == "robomimic" and detected["views_read"] == ["agentview", "robot0_eye_in_hand"]
    assert detected["length"] == LENGTH and detected["task"] == "Lift"
    assert [p.name for p in found["recordings"]] == ["Lift__demo_4.rrd"]
    tested = sorted(row["key"].split("/")[-1] for row in found["evaluation"]["trajectories"])
    assert tested == ["demo_4", "demo_5", "demo_6", "demo_7"]


def test_libero_names_the_task_and_views_picks_and_renames(tmp_path: Path) -> None:
    path = write_robomimic(
        tmp_path / "libero.hdf5",
        frame,
        demos=2,
        length=LENGTH,
        cameras=("agentview_rgb", "eye_in_hand_rgb"),
        instruction="put the bowl on the plate",
    )
    labels = write_labels(tmp_path / "labels.json.csv", {"demo_0": "grasp_wp2"}, ["demo_0", "demo_1"])
    dataset = load_dataset(path, labels=labels, views="eye_in_hand=wrist")
    assert [t.task for t in dataset] == ["put the bowl on the plate"] * 2 and dataset.views == ["wrist"]
    assert np.array_equal(dataset.episodes[0].views["wrist"][3].load(), frame(0, 1, 3))
    trajectory = load_trajectory(path, key="demo_1", views="agentview,eye_in_hand")
    assert trajectory.view_names == ["agentview", "eye_in_hand"] and trajectory.layout == "robomimic"
    memory = tmp_path / "memory"
    invoke(["build-memory", path, "--out", memory, "--labels", labels, "--views", "agentview=front"])
    info = invoke(["memory-info", memory])
    assert "read as     robomimic layout, views front" in info.stdout


def test_bad_hdf5_and_missing_views_are_named_errors_and_write_nothing(
    tmp_path: Path, robomimic: tuple[Path, Path]
) -> None:
    other = tmp_path / "other.hdf5"
    with h5py.File(other, "w") as handle:
        handle.create_dataset("trajectories/poses", data=np.zeros((5, 7)))
    memory = tmp_path / "memory"
    failed = invoke(["build-memory", other, "--out", memory], code=2)
    assert "is not robomimic-style" in failed.output and "/trajectories/poses (5, 7) float64" in failed.output
    path, labels = robomimic
    failed = invoke(
        ["build-memory", path, "--out", memory, "--labels", labels, "--views", "agentview,side"], code=2
    )
    assert (
        "no view 'side'" in failed.output and "its views are: agentview, robot0_eye_in_hand" in failed.output
    )
    assert not memory.exists()
    with pytest.raises(DataError, match="not robomimic-style"):
        load_dataset(other)


def red_over_blue(episode: int, camera: int, t: int) -> np.ndarray:
    """A frame whose colours and rows are told apart: red on top, blue below, a grey bar at row t."""
    image = np.zeros((32, 32, 3), np.uint8)
    image[:16] = (200, 10 * camera, 20 + episode)
    image[16:] = (30, 10 * camera, 210)
    image[t] = 128
    return image


def test_aloha_jpeg_rows_read_as_the_camera_gave_them(tmp_path: Path) -> None:
    """record_episodes.py encodes the RGB array as it is; reading it back must not swap red and blue."""
    folder = write_aloha(tmp_path / "transfer_cube", red_over_blue, episodes=2, length=4, compress=True)
    trajectory = load_dataset(folder, task="transfer").episodes[1]
    read = trajectory.views["cam_left_wrist"][2].load().astype(int)
    written = red_over_blue(1, 1, 2).astype(int)
    assert np.abs(read - written).mean() < 8  # JPEG's error at the edges; swapped, it is over 100
    assert read[4:12, :, 0].mean() > 190 and read[4:12, :, 2].mean() < 35  # red stays on top
    assert read[20:28, :, 2].mean() > 200 and read[20:28, :, 0].mean() < 40
    reference = trajectory.views["cam_left_wrist"][2].reference  # a memory entry's image reads the same
    assert np.array_equal(read_frame(reference), read)


def test_libero_opengl_frames_are_turned_upright(tmp_path: Path) -> None:
    path = write_robomimic(
        tmp_path / "TASK0_demo.hdf5",
        red_over_blue,
        demos=2,
        length=6,
        cameras=("agentview_rgb", "eye_in_hand_rgb"),
        instruction="open the top drawer",
        opengl=True,
    )
    plain = tmp_path / "plain.hdf5"  # the same rows without the attribute are another image
    shutil.copy(path, plain)
    with h5py.File(plain, "a") as handle:
        assert np.array_equal(handle["data/demo_1/obs/agentview_rgb"][3], red_over_blue(1, 0, 3)[::-1])
        del handle["data"].attrs["macros_image_convention"]
    frames = load_dataset(path).episodes[1].views["agentview"]
    assert np.array_equal(frames[3].load(), red_over_blue(1, 0, 3))
    assert np.array_equal(read_frame(frames[3].reference), red_over_blue(1, 0, 3))
    unflipped = load_dataset(plain).episodes[1].views["agentview"]
    assert np.array_equal(unflipped[3].load(), red_over_blue(1, 0, 3)[::-1])
    assert unflipped[3].content_key() != frames[3].content_key()


def aloha_labels(tmp_path: Path, folder: Path, episodes: int) -> tuple[Path, dict[int, str]]:
    """Two failures on each side of the hash split (the layout has no splits of its own)."""
    sides: dict[str, list[int]] = {}
    for e in range(episodes):
        key = Trajectory(task=folder.name, episode=f"episode_{e}", views={})
        sides.setdefault(split_of(key, has_splits=False, test_fraction=0.5), []).append(e)
    symbols = {e: "grasp_wp2" for side in sides.values() for e in side[:2]}
    labels = write_labels(
        tmp_path / "labels.csv",
        {f"episode_{e}": s for e, s in symbols.items()},
        [f"episode_{e}" for e in range(episodes)],
    )
    return labels, symbols


@pytest.mark.slow  # an end-to-end run of every verb: the full lane
@pytest.mark.parametrize("compress", [False, True])
def test_aloha_episodes_raw_or_jpeg_through_every_verb(tmp_path: Path, compress: bool) -> None:
    folder = tmp_path / "aloha_transfer_cube"
    episodes = 10
    labels, symbols = aloha_labels(tmp_path, folder, episodes)
    write_aloha(
        folder, lambda e, c, t: frame(e, c, t, symbols), episodes=episodes, length=LENGTH, compress=compress
    )
    dataset = load_dataset(folder, labels=labels)
    assert dataset.layout == "aloha" and dataset.views == ["cam_high", "cam_left_wrist"]
    trajectory = next(t for t in dataset if t.episode == "episode_3")
    assert trajectory.task == "aloha_transfer_cube" and trajectory.length == LENGTH
    read, written = trajectory.views["cam_left_wrist"][6].load(), frame(3, 1, 6, symbols)
    error = np.abs(read.astype(int) - written.astype(int))
    if compress:  # what ACT's cv2.imdecode(row, 1) gives, exactly; a few grey levels from what was encoded
        jpeg = cv2.imencode(".jpg", written, [int(cv2.IMWRITE_JPEG_QUALITY), 90])[1]
        assert np.array_equal(read, cv2.imdecode(jpeg, cv2.IMREAD_COLOR))
        assert 0 < error.mean() < 4
    else:
        assert error.max() == 0
    found = run_pipeline(tmp_path, folder, trajectory="episode_3", options=["--labels", labels])
    assert found["info"]["layout"] == "aloha" and found["detect"]["views_read"] == [
        "cam_high",
        "cam_left_wrist",
    ]
    assert _failure_views_to_their_end(found["memory"]) == 8 and len(found["recordings"]) == 1
    assert {row["key"].split("/")[-1] for row in found["evaluation"]["trajectories"]} <= {
        f"episode_{e}" for e in range(episodes)
    }


def _failure_views_to_their_end(memory: Path) -> int:
    """The failure views of a (dense) memory, each checked to keep frames in order up to its last frame."""
    frames: dict[tuple[str, str], list[int]] = {}
    for entry in FailureMemory.load(memory).entries:
        frames.setdefault((entry.episode, entry.view), []).append(-1 if entry.frame is None else entry.frame)
    assert all(
        kept == sorted(kept) and kept[0] >= 1 and kept[-1] == LENGTH - 1 for kept in frames.values()
    ), frames
    return len(frames)


def test_a_first_demo_of_no_frames_or_a_wider_state_leaves_the_other_demos_their_signals(
    tmp_path: Path, robomimic: tuple[Path, Path]
) -> None:
    """Issue 50: the task's signal layout is decided by all its demos; demo_0 with no rows, and demo_6 with a
    5-d `obs/robot0_eef_pos` among 3-d ones (unnamed dimensions: `0`, `1`, …), are each listed as skipped for
    signals with the reason, never cut to fit, while every other demo keeps the signal."""
    path, labels = robomimic
    with h5py.File(path, "a") as handle:
        empty = handle["data/demo_0"]
        for name in ("actions", "obs"):
            del empty[name]
        empty.attrs["num_samples"] = 0
        empty.create_dataset("actions", data=np.zeros((0, 7)))
        obs = empty.create_group("obs")
        for camera in ("agentview_image", "robot0_eye_in_hand_image"):
            obs.create_dataset(camera, data=np.zeros((0, 32, 32, 3), np.uint8))
        obs.create_dataset("robot0_eef_pos", data=np.zeros((0, 3)))
        wider = handle["data/demo_6/obs"]
        held = wider["robot0_eef_pos"][()]
        del wider["robot0_eef_pos"]
        wider.create_dataset("robot0_eef_pos", data=np.concatenate([held, np.ones((LENGTH, 2))], axis=1))
    memory = tmp_path / "memory"
    built = invoke(["build-memory", path, "--out", memory, "--labels", labels], code=3)
    listed = [line for line in built.output.splitlines() if "signals not used" in line]
    assert len(listed) == 2, built.output
    assert "demo_0" in listed[0] and "no rows" in listed[0]
    assert (
        "demo_6" in listed[1]
        and "has 5 dimension(s) (0, 1, 2, 3, 4), but the task's runs have 3" in listed[1]
    )
    signals = FailureMemory.load(memory).signals
    assert signals is not None
    task = signals.task("Lift")
    assert task is not None and task.layout.state == (("obs/robot0_eef_pos", ("0", "1", "2")),)
    kept = {*task.rows["failure"].episodes.tolist(), *task.rows["success"].episodes.tolist()}
    assert kept == {f"demo_{d}" for d in range(1, 8)} - {"demo_6"}
