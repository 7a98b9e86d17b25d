"""Video camera streams rendered by the real headless Rerun viewer: the camera panel shows the frame."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from environment import require_ffmpeg, require_viewer
from lerobot_writer import encode_video as write_mp4
from synthetic import synthetic_frame, write_episode

from rfr_viz.codecs import CameraCodec
from rfr_viz.recordings.replay import record_replay
from rfr_viz.viewer.control import render_screenshot
from rfr_viz.viewer.rrd import recording_properties
from robofailring import (
    CachedEncoder,
    FailureDetector,
    FailureMemory,
    load_encoder,
    load_trajectory,
)
from robofailring.data.images import write_png

pytestmark = pytest.mark.viewer
LENGTH, SIZE, SHOWN, OTHER = 40, 96, 33, 5


def _panel_image(png: bytes) -> np.ndarray:
    """The picture inside a camera panel screenshot: the box of pixels that differ from its background."""
    panel = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert panel is not None
    background = panel[2, 2].astype(np.int32)
    ys, xs = np.nonzero(np.abs(panel.astype(np.int32) - background).sum(axis=2) > 24)
    assert ys.size > 0, "the camera panel is blank"
    crop = panel[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    return cv2.cvtColor(cv2.resize(crop, (SIZE, SIZE), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2RGB)


def _difference(shown: np.ndarray, source: np.ndarray) -> float:
    """Mean absolute difference after matching each channel's gain (the viewer draws a little darker)."""
    shown_f, source_f = shown.reshape(-1, 3).astype(np.float64), source.reshape(-1, 3).astype(np.float64)
    gain = (shown_f * source_f).sum(axis=0) / np.maximum((source_f**2).sum(axis=0), 1e-9)
    return float(np.abs(shown_f - source_f * gain).mean())


@pytest.mark.parametrize("codec", [CameraCodec.AV1, CameraCodec.H264, CameraCodec.JPEG])
def test_the_camera_panel_shows_the_video_frame(
    codec: CameraCodec, pixels_memory: FailureMemory, tmp_path: Path
) -> None:
    require_viewer()
    if codec is CameraCodec.H264:
        require_ffmpeg()
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    folder = write_episode(tmp_path / "push_cube_slip_wp3_episode5", "push_cube", "slip_wp3", length=LENGTH)
    frames = [synthetic_frame("push_cube", "slip_wp3", 0, t, LENGTH, size=SIZE) for t in range(LENGTH)]
    for t, frame in enumerate(frames):
        write_png(folder / f"front_{t}.png", frame)
    trajectory = load_trajectory(folder)
    trace = FailureDetector(pixels_memory, encoder, k=2).run(trajectory)
    recording = record_replay(trajectory, trace, out=tmp_path / f"{codec.value}.rrd", camera_codec=codec)
    shot = render_screenshot(
        recording, tmp_path / "shot.png", frame=SHOWN, views=["/camera/front"], settle=1.5
    )
    assert shot.errors == [], shot.errors
    shown = _panel_image(shot.views["/camera/front"])
    # the panel holds frame 33 itself: close to its pixels, and far from another frame's
    assert _difference(shown, frames[SHOWN]) < 3.5
    assert _difference(shown, frames[OTHER]) > 2 * _difference(shown, frames[SHOWN])


def test_a_video_source_logged_as_its_own_samples_renders(
    pixels_memory: FailureMemory, tmp_path: Path
) -> None:
    """An AV1 `<view>.mp4` kept as the file's samples (rfr_viz.panels.video_passthrough) shows its frames."""
    require_viewer()
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    folder = tmp_path / "push_cube_slip_wp3_episode5"
    frames = [synthetic_frame("push_cube", "slip_wp3", 0, t, LENGTH, size=SIZE) for t in range(LENGTH)]
    write_mp4(folder / "front.mp4", frames, 10, "av1")
    trajectory = load_trajectory(folder)
    trace = FailureDetector(pixels_memory, encoder, k=2).run(trajectory)
    recording = record_replay(trajectory, trace, out=tmp_path / "kept.rrd", camera_codec=CameraCodec.AV1)
    assert recording_properties(recording, group="camera")["as_recorded"] == "front"
    shot = render_screenshot(
        recording, tmp_path / "shot.png", frame=SHOWN, views=["/camera/front"], settle=1.5
    )
    assert shot.errors == [], shot.errors
    shown = _panel_image(shot.views["/camera/front"])
    assert _difference(shown, frames[SHOWN]) < 3.5
    assert _difference(shown, frames[OTHER]) > 2 * _difference(shown, frames[SHOWN])
