"""A frame's reference is parsed once (`FrameRef`) and read once: the memory, the VLM and the recordings read
a video frame, an HDF5 row, a bag message and an image file the same way (docs/architecture.md, data/)."""

from __future__ import annotations

import base64
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from lerobot_writer import encode_video, scene

from rfr_viz.panels.images import reference_jpeg as recorded_jpeg
from robofailring import load_dataset
from robofailring.data.frame_ref import Container, FrameRef, read_frame, reference_jpeg
from robofailring.data.images import encode_jpeg, write_png
from robofailring.errors import DataError
from robofailring.explain.vlm import image_data_url
from robofailring.memory.image_roots import ImageRoots
from robofailring.memory.references import reference_file, relocate

paths = st.text(st.characters(blacklist_characters="\x00#&"), min_size=1, max_size=30).filter(
    lambda text: not text.startswith("<")
)


@given(file=paths, index=st.integers(0, 10**6), inner=paths)
def test_each_form_is_written_and_parsed_back_as_the_same_value(file: str, index: int, inner: str) -> None:
    for made in (
        FrameRef.video(file, index),
        FrameRef.hdf5(file, "/" + inner, index),
        FrameRef.bag(file, inner, index),
    ):
        parsed = FrameRef.parse(str(made))
        assert parsed == made and parsed.file == file and parsed.index == index
        assert parsed.fragment and parsed.moved("/elsewhere/x").file == "/elsewhere/x"
        assert parsed.moved("/elsewhere/x").fragment == parsed.fragment


@given(text=st.text(max_size=60))
def test_any_text_parses_and_reads_back_as_it_was_written(text: str) -> None:
    parsed = FrameRef.parse(text)
    assert str(parsed) == text and text.startswith(parsed.file) and parsed.file + parsed.fragment == text
    assert parsed.is_file == (not text.startswith("<"))


def test_the_forms_a_dataset_writes() -> None:
    assert FrameRef.parse("/d/ep/front_0.png") == FrameRef("/d/ep/front_0.png", "/d/ep/front_0.png")
    assert FrameRef.parse("<array>").is_file is False
    hdf5 = FrameRef.parse("/d/demo.hdf5#/data/demo_5/obs/agentview_image#frame=7")
    assert (hdf5.file, hdf5.container, hdf5.inner, hdf5.index) == (
        "/d/demo.hdf5",
        Container.HDF5,
        "/data/demo_5/obs/agentview_image",
        7,
    )
    bag = FrameRef.parse("/d/run.mcap#topic=/cam/image_raw&message=3")
    assert (bag.file, bag.container, bag.inner, bag.index) == (
        "/d/run.mcap",
        Container.BAG,
        "/cam/image_raw",
        3,
    )
    video = FrameRef.parse("/d/ep/front.mp4#frame=x")  # no number: a video frame that reads as none
    assert (video.container, video.index, read_frame(video)) == (Container.VIDEO, None, None)
    assert reference_file(str(bag)) == "/d/run.mcap" and reference_file(str(hdf5)) == "/d/demo.hdf5"


def test_memory_vlm_and_recording_read_a_video_frame_alike(tmp_path: Path) -> None:
    root = tmp_path / "videos"
    encode_video(root / "run_1" / "front.mp4", [scene(0, 0, t) for t in range(6)], 10, "h264")
    frame = load_dataset(root, task="pick_cube").episodes[0].views["front"][4]
    reference = frame.reference
    assert reference == f"{root / 'run_1' / 'front.mp4'}#frame=4"
    image = read_frame(reference)
    assert image is not None and np.array_equal(image, frame.load())
    expected = encode_jpeg(image, quality=80)
    assert recorded_jpeg(reference, ImageRoots.of(root)) == expected == reference_jpeg(reference, quality=80)
    assert recorded_jpeg(reference, ImageRoots.of(tmp_path / "other")) is None  # outside the roots: not read
    url = image_data_url(reference)
    assert base64.b64decode(url.split(",", 1)[1]) == encode_jpeg(image, quality=90)
    moved = tmp_path / "moved"
    (root / "run_1").rename(tmp_path / "run_1")
    moved.mkdir()
    (tmp_path / "run_1").rename(moved / "run_1")
    assert relocate(reference, moved) == f"{moved / 'run_1' / 'front.mp4'}#frame=4"


def test_a_file_passes_through_and_what_is_missing_is_named(tmp_path: Path) -> None:
    png = tmp_path / "front_0.png"
    write_png(png, np.full((8, 8, 3), 200, np.uint8))
    jpeg = tmp_path / "front_1.jpg"
    jpeg.write_bytes(encode_jpeg(np.full((8, 8, 3), 50, np.uint8)))
    assert reference_jpeg(str(jpeg), quality=80) == jpeg.read_bytes()
    decoded = cv2.imdecode(np.frombuffer(reference_jpeg(str(png), quality=80), np.uint8), cv2.IMREAD_COLOR)
    assert np.abs(decoded.astype(int) - 200).max() <= 2
    gone = f"{tmp_path / 'gone.mp4'}#frame=0"
    assert recorded_jpeg(gone, ImageRoots.of(tmp_path)) is None
    with pytest.raises(
        DataError, match=r"report image .*gone\.mp4#frame=0 is not a readable video frame; the VLM"
    ):
        image_data_url(gone)
    with pytest.raises(DataError, match=r"report image <array> is not a readable file; the VLM needs it"):
        image_data_url("<array>")
