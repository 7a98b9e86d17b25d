"""Camera streams as video: what the recording holds, read back from the file and decoded."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rrd import columns as rrd_columns
from rrd import psnr
from synthetic import synthetic_frame, write_episode

from rfr_viz.codecs import AUTO_AV1_PIXELS, CameraCodec, resolve_codec
from rfr_viz.panels.camera_video import KEYFRAME_INTERVAL, EncodedVideo, decode_video, encode_video
from rfr_viz.recordings.replay import record_replay
from rfr_viz.viewer.rrd import recording_properties
from robofailring import (
    CachedEncoder,
    FailureDetector,
    FailureMemory,
    load_encoder,
    load_trajectory,
)
from robofailring.data.images import write_png
from robofailring.data.model import Trajectory
from robofailring.detection.detector import DetectionTrace
from robofailring.errors import DataError

LENGTH = 40


@pytest.fixture(scope="module")
def replayed(
    pixels_memory_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Trajectory, DetectionTrace]:
    tmp = tmp_path_factory.mktemp("video")
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp / "cache")
    memory = FailureMemory.load(pixels_memory_dir)
    folder = tmp / "push_cube_slip_wp3_episode5"
    write_episode(folder, "push_cube", "slip_wp3", length=LENGTH)
    for view in ("front",):  # one view at 96 px, so that video has some real pixels to compress
        for t, png in enumerate(
            sorted(folder.glob(f"{view}_*.png"), key=lambda p: int(p.stem.split("_")[1]))
        ):
            write_png(png, synthetic_frame("push_cube", "slip_wp3", 0, t, LENGTH, size=96))
    trajectory = load_trajectory(folder)
    return trajectory, FailureDetector(memory, encoder, k=2).run(trajectory)


@pytest.mark.parametrize("codec", [CameraCodec.AV1, CameraCodec.H264])
def test_a_replay_stores_cameras_as_video_that_decodes_to_the_frames(
    replayed: tuple[Trajectory, DetectionTrace], codec: CameraCodec, tmp_path: Path
) -> None:
    trajectory, trace = replayed
    path = record_replay(trajectory, trace, out=tmp_path / "replay.rrd", camera_codec=codec)
    columns = rrd_columns(path, "/camera/front")
    assert columns["frame"] == list(range(trace.length))
    samples = [bytes(sample[0]) for sample in columns["VideoStream:sample"]]
    keyframes = [bool(key[0]) for key in columns["VideoStream:is_keyframe"]]
    assert [i for i, key in enumerate(keyframes) if key] == list(range(0, trace.length, KEYFRAME_INTERVAL))
    assert columns["VideoStream:codec"] == [[{"av1": 0x61763031, "h264": 0x61766331}[codec.value]]]
    # the samples in the file decode back to the source frames
    video = EncodedVideo(codec, samples, keyframes, 96, 96)
    decoded = decode_video(video)
    source = [frame.load() for frame in trajectory.views["front"][: trace.length]]
    assert len(decoded) == len(source)
    assert min(psnr(d, s) for d, s in zip(decoded, source, strict=True)) > 30.0
    # a frame decodes from its last keyframe alone (what the viewer does when scrubbing)
    start = KEYFRAME_INTERVAL
    tail = EncodedVideo(codec, samples[start:], keyframes[start:], 96, 96)
    assert psnr(decode_video(tail, upto=3)[-1], source[start + 3]) > 30.0
    # neighbour images stay images; the property says which codec the cameras use
    assert "EncodedImage:blob" in rrd_columns(path, "/neighbors/**")
    assert "EncodedImage:blob" not in rrd_columns(path, "/camera/**")
    properties = recording_properties(path, group="camera")
    assert properties["codec"] == codec.value and properties["keyframe_interval"] == KEYFRAME_INTERVAL


def test_auto_keeps_small_episodes_as_jpeg(
    replayed: tuple[Trajectory, DetectionTrace], tmp_path: Path
) -> None:
    trajectory, trace = replayed
    path = record_replay(trajectory, trace, out=tmp_path / "auto.rrd")  # default: auto
    assert "EncodedImage:blob" in rrd_columns(path, "/camera/front")
    assert recording_properties(path, group="camera")["codec"] == "jpeg"


def test_auto_threshold() -> None:
    side = 256
    below = AUTO_AV1_PIXELS // (side * side)
    assert resolve_codec("auto", width=side, height=side, frames=below) is CameraCodec.JPEG
    assert resolve_codec("auto", width=side, height=side, frames=below + 1) is CameraCodec.AV1
    assert resolve_codec("h264", width=8, height=8, frames=1) is CameraCodec.H264
    with pytest.raises(ValueError, match="mp4"):
        resolve_codec("mp4", width=8, height=8, frames=1)


def test_odd_sizes_are_padded_and_size_changes_are_an_error() -> None:
    frames = [synthetic_frame("t", None, 0, t, 12, size=64)[:63, :61] for t in range(12)]
    video = encode_video(frames, CameraCodec.AV1, fps=10.0)
    assert (video.width, video.height) == (62, 64) and len(video.samples) == 12
    assert decode_video(video)[5].shape == (64, 62, 3)
    with pytest.raises(DataError, match=r"cam \[front\]: frame 2 is 48×48 px"):
        encode_video(
            [*frames[:2], np.zeros((48, 48, 3), np.uint8)], CameraCodec.AV1, fps=10, source="cam [front]"
        )
