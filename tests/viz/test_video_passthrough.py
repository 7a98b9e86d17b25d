"""Video sources logged as their own samples when no re-encoding is needed, re-encoded otherwise."""

from __future__ import annotations

import re
from fractions import Fraction
from pathlib import Path

import av
import pytest
import rerun as rr
from lerobot_writer import encode_video as write_lerobot_mp4
from rrd import properties, psnr, rows
from synthetic import synthetic_frame

from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.camera_video import KEYFRAME_INTERVAL, EncodedVideo, decode_video
from rfr_viz.panels.cameras import log_camera_views
from rfr_viz.panels.scores import time_columns
from rfr_viz.paths import camera
from robofailring import load_trajectory

LENGTH = 40
FRAMES = [synthetic_frame("pick_cube", "grasp_wp2", 0, t, LENGTH, size=96) for t in range(LENGTH)]


def _write_h264(path: Path, gop: int) -> None:
    """H.264 without B-frames, a keyframe every `gop` frames (as a camera pipeline may record it)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=10)
        stream.options = {"g": str(gop), "crf": "23", "x264-params": "bframes=0"}
        stream.pix_fmt, stream.width, stream.height = "yuv420p", 96, 96
        stream.time_base = Fraction(1, 10)
        for index, image in enumerate(FRAMES):
            frame = av.VideoFrame.from_ndarray(image, format="rgb24")
            frame.pts = index
            container.mux(stream.encode(frame))
        container.mux(stream.encode())


def _packets(path: Path) -> list[bytes]:
    with av.open(str(path)) as container:
        return [bytes(p) for p in container.demux(container.streams.video[0]) if p.size]


def _record(episode: Path, codec: CameraCodec, out: Path) -> tuple[list[bytes], list[bool], str | None]:
    rec = rr.RecordingStream("test", recording_id=out.stem)
    rec.save(out)
    trajectory = load_trajectory(episode, task="pick_cube")
    log_camera_views(
        rec,
        trajectory,
        views=["front"],
        length=LENGTH,
        indexes=lambda frames: time_columns(frames, 10.0),
        codec=codec,
    )
    rec.flush()
    rec.disconnect()
    samples = rows(out, camera("front"), "VideoStream:sample")
    assert [frame for frame, _ in samples] == list(range(LENGTH))
    keyframes = [bool(k[0]) for _, k in rows(out, camera("front"), "VideoStream:is_keyframe")]
    kept = properties(out, "camera").get("as_recorded")
    return [bytes(s[0]) for _, s in samples], keyframes, kept


def _length_prefixed(packet: bytes) -> list[bytes]:
    """The NAL units of an MP4 H.264 sample (each after its 4-byte big-endian length)."""
    units, at = [], 0
    while at < len(packet):
        size = int.from_bytes(packet[at : at + 4], "big")
        units.append(packet[at + 4 : at + 4 + size])
        at += 4 + size
    return units


def _renders(codec: CameraCodec, samples: list[bytes], keyframes: list[bool]) -> None:
    decoded = decode_video(EncodedVideo(codec, samples, keyframes, 96, 96))
    assert len(decoded) == LENGTH
    assert min(psnr(d, s) for d, s in zip(decoded, FRAMES, strict=True)) > 30.0
    start = keyframes.index(True, 1)  # a later keyframe decodes on its own, as when scrubbing
    tail = decode_video(EncodedVideo(codec, samples[start:], keyframes[start:], 96, 96), upto=1)
    assert psnr(tail[-1], FRAMES[start + 1]) > 30.0


def test_an_av1_source_is_logged_as_its_own_samples(tmp_path: Path) -> None:
    write_lerobot_mp4(tmp_path / "ep" / "front.mp4", FRAMES, 10, "av1")  # a keyframe every 2 frames
    samples, keyframes, kept = _record(tmp_path / "ep", CameraCodec.AV1, tmp_path / "av1.rrd")
    assert kept == "front"  # the recording says so
    assert samples == _packets(tmp_path / "ep" / "front.mp4")  # the file's bytes, not re-encoded
    assert [i for i, key in enumerate(keyframes) if key] == list(range(0, LENGTH, 2))
    _renders(CameraCodec.AV1, samples, keyframes)


def test_an_h264_source_without_b_frames_is_logged_as_annex_b(tmp_path: Path) -> None:
    _write_h264(tmp_path / "ep" / "front.mp4", gop=10)
    samples, keyframes, kept = _record(tmp_path / "ep", CameraCodec.H264, tmp_path / "h264.rrd")
    assert kept == "front"
    packets = _packets(tmp_path / "ep" / "front.mp4")
    assert [i for i, key in enumerate(keyframes) if key] == list(range(0, LENGTH, 10))  # the source's
    for sample, packet, key in zip(samples, packets, keyframes, strict=True):
        assert sample.startswith(b"\x00\x00\x00\x01")  # Annex B start codes, not MP4 length prefixes
        units = [unit for unit in re.split(b"\x00\x00\x00\x01|\x00\x00\x01", sample) if unit]
        parameter_sets = [unit for unit in units if unit[0] & 0x1F in (7, 8)]  # SPS, PPS
        assert [unit for unit in units if unit not in parameter_sets] == _length_prefixed(packet)
        assert bool(parameter_sets) == key  # before every keyframe, so that it decodes on its own
    _renders(CameraCodec.H264, samples, keyframes)


@pytest.mark.parametrize(
    ("source", "codec"),
    [("h264-b-frames", CameraCodec.H264), ("av1", CameraCodec.H264), ("h264", CameraCodec.AV1)],
)
def test_other_sources_are_re_encoded(tmp_path: Path, source: str, codec: CameraCodec) -> None:
    path = tmp_path / "ep" / "front.mp4"
    if source == "h264":
        _write_h264(path, gop=10)
    else:  # lerobot's x264 settings keep B-frames; its AV1 has keyframes every 2 frames
        write_lerobot_mp4(path, FRAMES, 10, source.split("-")[0])
    samples, keyframes, kept = _record(tmp_path / "ep", codec, tmp_path / "out.rrd")
    assert kept is None
    assert not set(samples) & set(_packets(path))
    assert [i for i, key in enumerate(keyframes) if key] == list(range(0, LENGTH, KEYFRAME_INTERVAL))
    _renders(codec, samples, keyframes)
