"""Folders of robomimic-style files: LIBERO's suite folder, MimicGen's demo.hdf5 beside demo_failed.hdf5."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from hdf5_writer import write_robomimic
from pipeline import invoke
from synthetic import synthetic_frame

from robofailring import load_dataset, load_trajectory
from robofailring.data.model import Outcome
from robofailring.errors import DataError

LENGTH = 5
INSTRUCTIONS = ("pick up the black bowl and place it on the plate", "open the top drawer")


def frame(demo: int, camera: int, t: int) -> np.ndarray:
    return synthetic_frame("pick_cube", None, camera + 2 * demo, t, LENGTH, size=24)


def libero_suite(folder: Path) -> Path:
    for number, instruction in enumerate(INSTRUCTIONS):
        write_robomimic(
            folder / f"TASK{number}_demo.hdf5",
            lambda demo, camera, t, number=number: frame(demo + 10 * number, camera, t),
            demos=2,
            length=LENGTH,
            cameras=("agentview_rgb", "eye_in_hand_rgb"),
            instruction=instruction,
            opengl=True,
        )
    return folder


def test_a_libero_suite_folder_is_one_dataset_keyed_by_file_and_demo(tmp_path: Path) -> None:
    folder = libero_suite(tmp_path / "libero_spatial")
    (folder / "README.txt").write_text("suite notes")
    with h5py.File(folder / "stats.hdf5", "w") as handle:
        handle.create_dataset("mean", data=np.zeros(3))
    dataset = load_dataset(folder)
    assert dataset.layout == "robomimic" and dataset.views == ["agentview", "eye_in_hand"]
    assert [t.episode for t in dataset] == [
        "TASK0_demo/demo_0", "TASK0_demo/demo_1", "TASK1_demo/demo_0", "TASK1_demo/demo_1",
    ]  # fmt: skip
    assert [t.task for t in dataset] == [INSTRUCTIONS[0]] * 2 + [INSTRUCTIONS[1]] * 2
    assert all(t.outcome is None and t.symbol is None for t in dataset)  # LIBERO's demos are not labelled
    third = dataset.episodes[2]
    assert np.array_equal(third.views["eye_in_hand"][3].load(), frame(10, 1, 3))  # upright, its own file
    assert {(s.path.name, s.reason.split(" (")[0]) for s in dataset.skipped} == {
        ("README.txt", "not a robomimic-style HDF5 file"),
        ("stats.hdf5", "not a robomimic-style HDF5 file"),
    }
    chosen = load_trajectory(folder, key="TASK1_demo/demo_1", views="agentview")
    assert chosen.view_names == ["agentview"] and chosen.task == INSTRUCTIONS[1]
    assert np.array_equal(chosen.views["agentview"][0].load(), frame(11, 0, 0))


def test_labels_name_a_demo_of_a_folder_by_its_whole_key(tmp_path: Path) -> None:
    folder = libero_suite(tmp_path / "libero_spatial")
    labels = tmp_path / "labels.csv"
    labels.write_text(
        "episode,outcome,symbol\nTASK1_demo/demo_0,failure,grasp_wp2\nTASK0_demo/demo_1,success,\n"
    )
    by_key = {t.episode: t for t in load_dataset(folder, labels=labels)}
    assert by_key["TASK1_demo/demo_0"].symbol == "grasp_wp2"
    assert by_key["TASK0_demo/demo_1"].outcome is Outcome.SUCCESS
    assert by_key["TASK0_demo/demo_0"].outcome is None and by_key["TASK1_demo/demo_1"].outcome is None
    labels.write_text("episode,outcome,symbol\ndemo_0,failure,grasp_wp2\n")  # which file's demo_0?
    with pytest.raises(
        DataError, match=r"row 1: episode 'demo_0' names 2 episodes \(TASK0_demo/demo_0, TASK1"
    ):
        load_dataset(folder, labels=labels)


def test_mimicgen_failed_demos_are_failures_and_its_demos_unlabelled(tmp_path: Path) -> None:
    folder = tmp_path / "mimicgen_stack"
    for name in ("demo", "demo_failed"):
        write_robomimic(folder / f"{name}.hdf5", frame, demos=3, length=LENGTH, env_name="Stack_D0")
    dataset = load_dataset(folder)
    assert dataset.layout == "robomimic" and dataset.labelled and dataset.skipped == []
    outcomes = {t.episode: (t.outcome, t.symbol) for t in dataset}
    assert outcomes == {
        **{f"demo/demo_{i}": (None, None) for i in range(3)},
        **{f"demo_failed/demo_{i}": (Outcome.FAILURE, "failure") for i in range(3)},
    }
    labels = tmp_path / "labels.csv"  # a labels file wins over the file's name
    labels.write_text("episode,outcome,symbol\ndemo_failed/demo_1,success,\ndemo/demo_2,failure,slip_wp1\n")
    relabelled = {t.episode: (t.outcome, t.symbol) for t in load_dataset(folder, labels=labels)}
    assert relabelled["demo_failed/demo_1"] == (Outcome.SUCCESS, None)
    assert relabelled["demo_failed/demo_0"] == (Outcome.FAILURE, "failure")
    assert relabelled["demo/demo_2"] == (Outcome.FAILURE, "slip_wp1")
    alone = load_dataset(folder / "demo_failed.hdf5")  # one file keeps the demo names as keys
    assert [(t.episode, t.outcome) for t in alone] == [(f"demo_{i}", Outcome.FAILURE) for i in range(3)]


def test_a_folder_of_one_file_keeps_demo_keys_and_a_minority_is_no_dataset(tmp_path: Path) -> None:
    folder = tmp_path / "lift"
    write_robomimic(folder / "image.hdf5", frame, demos=2, length=LENGTH)
    with h5py.File(folder / "low_dim.hdf5", "w") as handle:  # the structure, no camera: listed, not read
        handle.create_dataset("data/demo_0/obs/robot0_eef_pos", data=np.zeros((LENGTH, 3)))
    dataset = load_dataset(folder)
    assert [t.episode for t in dataset] == ["image/demo_0", "image/demo_1"]
    (skipped,) = dataset.skipped
    assert skipped.path.name == "low_dim.hdf5" and "no demo has an image observation" in skipped.reason
    (folder / "low_dim.hdf5").unlink()
    assert [t.episode for t in load_dataset(folder)] == ["demo_0", "demo_1"]
    for name in ("a", "b"):
        with h5py.File(folder / f"{name}.hdf5", "w") as handle:
            handle.create_dataset("poses", data=np.zeros((4, 7)))
    with pytest.raises(DataError, match="matches no known dataset layout"):
        load_dataset(folder)


def test_build_memory_says_which_runs_are_unlabelled_not_ignored(tmp_path: Path) -> None:
    folder = tmp_path / "mimicgen_stack"
    for name in ("demo", "demo_failed"):
        write_robomimic(folder / f"{name}.hdf5", frame, demos=3, length=LENGTH, env_name="Stack_D0")
    labels = tmp_path / "labels.csv"
    labels.write_text("episode,outcome,symbol\ndemo/demo_0,success,\n")
    built = invoke(
        [
            "build-memory",
            folder,
            "--labels",
            labels,
            "--out",
            tmp_path / "memory",
            "--cache-dir",
            tmp_path / "c",
        ]
    )
    assert (
        "from 3 failure trajectories over 1 tasks; 1 non-failures ignored; "
        "2 unlabelled run(s) not used (give their outcome with --labels)" in built.stdout
    )
