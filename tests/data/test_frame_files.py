"""Image files as frames: numbers with a decimal part (timestamps) order by value; 16-bit PNGs are no colour view."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import pytest

from robofailring import load_dataset, load_trajectory
from robofailring.data.images import decode_image, write_png
from robofailring.data.model import Frame, FrameFiles
from robofailring.errors import DataError


def write_frames(folder: Path, names: list[str]) -> None:
    """PNG frames whose first pixel holds their place in time (`names` are in time order)."""
    folder.mkdir(parents=True, exist_ok=True)
    for place, name in enumerate(names):
        write_png(folder / name, np.full((8, 8, 3), place, np.uint8))


def places(frames: Sequence[Frame]) -> list[int]:
    return [int(frame.load()[0, 0, 0]) for frame in frames]


def test_timestamp_names_order_by_their_whole_value(tmp_path: Path) -> None:
    """`1700000000.800000` is frame 1700000000.8, before `1700000001.100000` (its fraction 800000 is not)."""
    stamps = [f"{1_700_000_000 + 0.8 + 0.3 * t:.6f}" for t in range(5)]
    episode = tmp_path / "run_0"
    write_frames(episode / "front", [f"{stamp}.png" for stamp in stamps])
    write_frames(episode / "wrist", [f"frame_{stamp}.png" for stamp in stamps])
    trajectory = load_trajectory(episode, task="t")
    assert places(trajectory.views["front"]) == places(trajectory.views["wrist"]) == [0, 1, 2, 3, 4]
    flat = tmp_path / "flat"
    write_frames(flat, [f"{stamp}.png" for stamp in stamps])  # a number alone: the view `image`
    assert places(load_trajectory(flat, task="t").views["image"]) == [0, 1, 2, 3, 4]


def test_nanosecond_stamps_a_float_cannot_tell_apart_are_two_frames(tmp_path: Path) -> None:
    names = ["1700000000000000001.png", "1700000000000000002.png", "1700000000000000010.png"]
    assert float(names[0][:-4]) == float(names[1][:-4])
    episode = tmp_path / "ep"
    write_frames(episode / "front", names)
    write_frames(episode / "wrist", names)
    assert places(load_trajectory(episode, task="t").views["front"]) == [0, 1, 2]


def test_a_16_bit_png_view_is_listed_as_not_read(tmp_path: Path) -> None:
    for run in ("run_0", "run_1"):
        write_frames(tmp_path / "rgbd" / run / "rgb", [f"{t}.png" for t in range(3)])
        (tmp_path / "rgbd" / run / "depth").mkdir()
        for t in range(3):
            cv2.imwrite(
                str(tmp_path / "rgbd" / run / "depth" / f"{t}.png"), np.full((8, 8), 1000 + t, np.uint16)
            )
    dataset = load_dataset(tmp_path / "rgbd", task="t")
    assert dataset.layout == "images" and [t.view_names for t in dataset] == [["rgb"], ["rgb"]]
    assert [(s.path, s.view, s.reason) for s in dataset.skipped] == [
        (
            tmp_path / "rgbd" / run / "depth",
            "depth",
            "view 'depth': 16-bit PNG images (a depth camera?), not 8-bit colour: not read",
        )
        for run in ("run_0", "run_1")
    ]
    with pytest.raises(
        DataError, match=r"view 'depth' of trajectory t/run_1 .* is not read: view 'depth': 16-bit"
    ):
        load_trajectory(tmp_path / "rgbd", key="run_1", task="t", views="depth")
    depth = (tmp_path / "rgbd" / "run_0" / "depth" / "2.png").read_bytes()
    with pytest.raises(DataError, match=r"image 2\.png has 16-bit samples \(a depth map\?\)"):
        decode_image(depth, source="2.png")  # a frame decoded on its own is not scaled to 8 bits either


@pytest.mark.parametrize(
    "names",
    [
        [f"front_{i}.png" for i in range(12)],  # numbered in one run, not padded
        [f"frame_{i:04d}.png" for i in range(3, 15)],  # padded, starting past 0
        ["0.png", "2.png", "5.png", "11.png"],  # gaps: kept as names
        ["1700000000.800000.png", "1700000001.100000.png", "1700000001.400000.png"],  # timestamps
    ],
)
def test_a_folder_of_frames_is_held_compactly_and_reads_as_its_files(
    tmp_path: Path, names: list[str]
) -> None:
    """A large dataset lists 600,000 frames: the loader keeps a folder's names, not a `Frame` each, and
    indexing, slicing, iterating and comparing give exactly the files in time order."""
    write_frames(tmp_path / "run" / "front", names)
    frames = load_trajectory(tmp_path / "run", task="pick").views["front"]
    assert isinstance(frames, FrameFiles)
    expected = tuple(Frame(path=tmp_path / "run" / "front" / name) for name in names)
    assert len(frames) == len(names)
    assert list(frames) == list(expected)
    assert frames == expected and expected == frames
    assert frames[-1] == expected[-1] and frames[1:3] == list(expected[1:3])
    assert places(frames) == list(range(len(names)))
    with pytest.raises(IndexError):
        frames[len(names)]
    assert frames != expected[:-1]
