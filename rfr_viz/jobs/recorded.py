"""`Recordings`: which trajectories a replay or a comparison records, and how, as one value (no Rerun: the
command line builds it before any recording is made)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rfr_viz.codecs import CameraCodec
from rfr_viz.paths import DEFAULT_OUT
from robofailring.data.model import FPS_RANGE, in_fps_range
from robofailring.errors import SettingError


def check_fps(fps: float | None) -> float | None:
    """`--fps`, a `time` timeline rate within `FPS_RANGE` (SettingError otherwise): a frame's time in
    nanoseconds must fit Rerun's int64 (at 1e-300 fps frame 1 is at infinity, an OverflowError). The data's
    own rate is checked where it is read (`Trajectory.frame_rate`)."""
    low, high = FPS_RANGE
    if fps is not None and not in_fps_range(fps):
        raise SettingError(f"--fps must be a number of frames per second from {low:g} to {high:g}, got {fps}")
    return fps


@dataclass(frozen=True)
class Recordings:
    """Which trajectories a replay or a comparison records, and how: one `.rrd` each in `out`."""

    out: Path = DEFAULT_OUT  # folder of the .rrd files, one per trajectory
    trajectories: tuple[str, ...] = ()  # `<task>/<episode>` keys or episode names; empty = all
    leave_one_out: bool = False  # hide each trajectory's own episode from the memory
    fps: float | None = None  # "time" timeline rate; default: the data's, else 10
    camera_codec: CameraCodec = CameraCodec.AUTO  # jpeg, av1, h264, or auto (by size)

    def __post_init__(self) -> None:  # a bad setting fails before the memory is read
        check_fps(self.fps)
