"""Blind or broken frames (issue 45, item 3): a frame the encoder sees as nothing (black, one colour, or
an embedding that is not a number) is never stored in a memory nor scored, and is listed with the reason;
the verb ends with the "some inputs skipped" status (3). A camera that goes dark mid-run is said."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli
from synthetic import write_project_dataset

from robofailring import FailureMemory
from robofailring.data.images import read_image, write_png

LENGTH = 16


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("blank") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=4,
        length=LENGTH,
    )


def _black(folder: Path, view: str, frames: range) -> None:
    for t in frames:
        path = folder / f"{view}_{t}.png"
        write_png(path, np.zeros_like(read_image(path)))


def test_blank_frames_are_never_stored_in_a_memory(data: Path, cache: list[str], tmp_path: Path) -> None:
    copy = Path(shutil.copytree(data, tmp_path / "data"))
    _black(copy / "pick_cube_grasp_wp2_episode0", "front", range(4, 12))  # a failure's camera gone dark
    _black(copy / "pick_cube_success_episode2", "wrist", range(LENGTH))  # a success's camera dark throughout
    memory = tmp_path / "memory"
    built = cli("build-memory", copy, "--out", memory, "--split", "train", *cache)
    assert built.exit_code == 3, built.output  # some inputs skipped
    assert "pick_cube/pick_cube_grasp_wp2_episode0 view front: frame(s) 4–11 of 16 are blank" in built.output
    assert "pick_cube/pick_cube_success_episode2 view wrist: its first frame is blank" in built.output
    loaded = FailureMemory.load(memory)
    assert np.all(np.linalg.norm(loaded.vectors, axis=1) > 0.5)  # no blank pair in the failure memory
    frames = {(entry.episode, entry.view, entry.frame) for entry in loaded.entries if entry.view == "front"}
    assert not any(
        episode == "pick_cube_grasp_wp2_episode0" and 4 <= (frame or 0) <= 11 for episode, _, frame in frames
    )
    assert loaded.successes is not None
    views = {(run.episode, run.view) for run in loaded.successes.runs}
    assert ("pick_cube_success_episode2", "wrist") not in views and (
        "pick_cube_success_episode2",
        "front",
    ) in views


def test_a_camera_that_goes_dark_is_said_not_passed_as_no_alarm(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    copy = Path(shutil.copytree(data, tmp_path / "data"))
    episode = "pick_cube_success_episode1"
    _black(copy / episode, "front", range(4, 12))
    found = cli("detect", copy, "--memory", memory, "--trajectory", episode, "--json", *cache)
    assert found.exit_code == 3, found.output
    trace = json.loads(found.stdout)
    (skipped,) = [s for s in trace["skipped_inputs"] if "front" in s["reason"]]
    assert "view front: 8 of 16 scored frame(s) (4–11) are blank to the encoder" in skipped["reason"]
    assert all(value is None for value in trace["views"]["front"]["contrast"][4:12])
    _black(copy / episode, "wrist", range(LENGTH))
    _black(copy / episode, "front", range(LENGTH))
    _black(copy / episode, "overhead", range(LENGTH))
    dark = cli("detect", copy, "--memory", memory, "--trajectory", episode, *cache)
    assert dark.exit_code == 3, dark.output
    assert dark.output.count("its first frame is blank to the encoder") == 3
    assert "no frame scored" in dark.output
