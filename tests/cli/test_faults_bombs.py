"""Decompression bombs (issue 35, item 7): a small file declaring a huge frame is refused before it is decoded.

A 2.6 MB PNG of 30000×30000 or a 7 KB HDF5 of (3, 20000, 20000, 3) decoded to 5–7 GB. Every decoder
checks the frame size its file declares (the PNG/JPEG/BMP/WebP header, the HDF5 dataset's shape, the
video stream's size, a ROS image's width and height) against `ROBOFAILRING_MAX_FRAME_PIXELS` (50
megapixels by default) and stops with one error naming the file and the setting. The files here are
real and small; what they declare is large, and nothing the size of a frame is ever allocated.
"""

from __future__ import annotations

import shutil
import struct
import tracemalloc
import zlib
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from fault_helpers import cli, refused, tree
from hdf5_writer import write_aloha
from lerobot_writer import encode_video
from rosbag_writer import write_bag
from synthetic import synthetic_frame

from robofailring import load_dataset, load_trajectory
from robofailring.data.images import MAX_FRAME_PIXELS, MAX_FRAME_PIXELS_SETTING, encoded_size, read_image
from robofailring.errors import DataError, SettingError

EPISODE = "pick_cube_grasp_wp2_episode0"  # an episode of the `data` fixture (tests/cli/conftest.py)


def declare_size(png: Path, width: int, height: int) -> Path:
    """Rewrite a PNG's header to declare width × height (its IHDR chunk and that chunk's CRC)."""
    data = bytearray(png.read_bytes())
    data[16:24] = struct.pack(">II", width, height)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    png.write_bytes(bytes(data))
    return png


def test_a_png_declaring_30000_by_30000_is_refused_naming_the_file_and_the_setting(
    memory: Path, data: Path, cache: list[str], tmp_path: Path
) -> None:
    episode = Path(shutil.copytree(data / EPISODE, tmp_path / "data" / EPISODE))
    bomb = declare_size(episode / "front_1.png", 30000, 30000)
    assert encoded_size(bomb.read_bytes()) == (30000, 30000) and bomb.stat().st_size < 10_000
    before = tree(memory)
    refused(
        cli("detect", episode, "--memory", memory, *cache),
        2,
        str(bomb),
        "30000×30000",
        f"{MAX_FRAME_PIXELS:,}",
        MAX_FRAME_PIXELS_SETTING,
    )
    out = tmp_path / "rebuilt"
    refused(cli("build-memory", episode.parent, "--out", out, *cache), 2, str(bomb), MAX_FRAME_PIXELS_SETTING)
    assert not out.exists() and tree(memory) == before


def test_the_setting_raises_and_lowers_the_limit_for_a_real_image(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    large = tmp_path / "large.png"  # 6 megapixels of one colour: a 20 KB file
    assert cv2.imwrite(str(large), np.full((2000, 3000, 3), 90, np.uint8))
    monkeypatch.setenv(MAX_FRAME_PIXELS_SETTING, "5_999_999")
    with pytest.raises(DataError, match=rf"{large}: a frame of 3000×2000 pixels .* at least 6000000"):
        read_image(large)
    monkeypatch.setenv(MAX_FRAME_PIXELS_SETTING, "6000000")
    assert read_image(large).shape == (2000, 3000, 3)
    monkeypatch.setenv(MAX_FRAME_PIXELS_SETTING, "lots")
    with pytest.raises(SettingError, match=f"{MAX_FRAME_PIXELS_SETTING} must be a whole number .* 'lots'"):
        read_image(large)


def test_a_malformed_setting_is_one_error_line(
    memory: Path, data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(MAX_FRAME_PIXELS_SETTING, "0")  # read when a frame is decoded: a cache not holding it
    fresh = ["--cache-dir", tmp_path / "cache"]
    refused(cli("detect", data / EPISODE, "--memory", memory, *fresh), 2, MAX_FRAME_PIXELS_SETTING, "'0'")


def hdf5_bomb(path: Path) -> Path:
    """An ALOHA episode whose camera declares (3, 20000, 20000, 3) uint8, chunked and compressed, never written."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as root:
        images = root.create_group("observations/images")
        images.create_dataset(
            "front", (3, 20000, 20000, 3), np.uint8, chunks=(1, 256, 256, 3), compression="gzip"
        )
        root.create_dataset("action", data=np.zeros((3, 14)))
    return path


def test_an_hdf5_declaring_3_by_20000_by_20000_frames_is_refused_without_reading_a_row(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    bomb = hdf5_bomb(tmp_path / "pick_cube" / "episode_0.hdf5")
    assert bomb.stat().st_size < 64_000  # 3.6 GB declared
    before = tree(memory)
    refused(
        cli("detect", bomb, "--memory", memory, *cache),
        2,
        f"{bomb}#/observations/images/front#frame=0",
        "20000×20000",
        MAX_FRAME_PIXELS_SETTING,
    )
    assert tree(memory) == before
    frame = load_trajectory(bomb).views["front"][0]
    tracemalloc.start()
    try:
        with pytest.raises(DataError, match=MAX_FRAME_PIXELS_SETTING):
            frame.load()
        with pytest.raises(DataError, match=MAX_FRAME_PIXELS_SETTING):
            frame.content_key()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 * 1024**2  # a row would be 1.2 GB: none was read


def test_encoded_hdf5_rows_longer_than_a_frame_are_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = write_aloha(
        tmp_path / "aloha",
        lambda e, c, t: synthetic_frame("pick_cube", None, c, t, 3, size=32),
        episodes=1,
        length=3,
        compress=True,
    )
    trajectory = load_trajectory(folder / "episode_0.hdf5")
    assert trajectory.views["cam_high"][0].load().shape == (32, 32, 3)
    monkeypatch.setenv(MAX_FRAME_PIXELS_SETTING, "100")  # rows of ~1 KB: more than 3 bytes a pixel of 100
    with pytest.raises(
        DataError, match=r"episode_0\.hdf5#/observations/images/cam_high#frame=1: an encoded row"
    ):
        trajectory.views["cam_high"][1].load()


def test_video_frames_over_the_limit_are_refused_before_decoding(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    episode = tmp_path / "videos" / EPISODE
    encode_video(
        episode / "front.mp4", [np.full((48, 64, 3), 30 * t, np.uint8) for t in range(3)], 10, "h264"
    )
    encode_video(
        episode / "wrist.mp4", [np.full((48, 64, 3), 30 * t, np.uint8) for t in range(3)], 10, "h264"
    )
    trajectory = load_trajectory(episode)
    assert trajectory.views["front"][2].load().shape == (48, 64, 3)
    monkeypatch.setenv(MAX_FRAME_PIXELS_SETTING, str(64 * 48 - 1))
    with pytest.raises(
        DataError, match=rf"video {episode / 'wrist.mp4'}: a frame of 64×48 .* {MAX_FRAME_PIXELS_SETTING}"
    ):
        load_trajectory(episode).views["wrist"][0].load()


def test_ros_images_over_the_limit_are_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bag = write_bag(
        tmp_path / "bags" / "run_1.bag",
        kind="ros1",
        topics=(("/cam/image_raw", "rgb8"), ("/cam/image_raw/compressed", "png")),
        frames=lambda number, t: synthetic_frame("pick_cube", None, number, t, 3, size=32),
        count=3,
    )
    (trajectory,) = load_dataset(bag.parent, task="pick_cube")
    monkeypatch.setenv(MAX_FRAME_PIXELS_SETTING, str(32 * 32 - 1))
    for view in trajectory.view_names:
        with pytest.raises(DataError, match=rf"{view}.*32×32 pixels .* {MAX_FRAME_PIXELS_SETTING}"):
            trajectory.views[view][0].load()
