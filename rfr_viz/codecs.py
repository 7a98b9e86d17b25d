"""The codecs a recording's camera streams are stored with, and how `auto` picks one.

No Rerun here: the command line offers the codecs before anything is recorded
(`rfr_viz.cli.options`); `rfr_viz.panels.camera_video` encodes them.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Final


class CameraCodec(StrEnum):
    """How `/camera/<view>` is stored: JPEG per frame, AV1 or H.264 video, or chosen by size."""

    JPEG = "jpeg"
    AV1 = "av1"
    H264 = "h264"
    AUTO = "auto"


#: `auto` picks AV1 when one view's stream has at least this many pixels (frames × width × height),
#: JPEG below: e.g. 256 px × 256 px × 31 frames. Measured by bench/bench_video.py (docs/codecs.md,
#: "Camera codecs"): below it a view's JPEGs take ~0.1 MB or less and AV1 saves under 0.1 MB at a lower PSNR;
#: at it AV1 takes 0.42× the bytes, on the real 256 px × 69-frame episode 0.14×, at 480 px 0.17×.
AUTO_AV1_PIXELS: Final[int] = 2_000_000


def resolve_codec(codec: CameraCodec | str, *, width: int, height: int, frames: int) -> CameraCodec:
    """The codec a view is stored with: `codec` itself, or for `auto` the choice by stream size."""
    codec = CameraCodec(codec)
    if codec is not CameraCodec.AUTO:
        return codec
    return CameraCodec.AV1 if frames * width * height >= AUTO_AV1_PIXELS else CameraCodec.JPEG
