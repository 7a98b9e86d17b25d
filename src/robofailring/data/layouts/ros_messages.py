"""ROS image messages as RGB: which `sensor_msgs/msg/Image` encodings and `CompressedImage` formats are
camera frames, and each decoded to (H, W, 3) uint8 (the bag reader's frames, `layout_rosbag`)."""

from __future__ import annotations

from typing import Any, Final

import numpy as np

from robofailring.data.images import check_frame_size, decode_image
from robofailring.errors import DataError

IMAGE: Final[str] = "sensor_msgs/msg/Image"
COMPRESSED: Final[str] = "sensor_msgs/msg/CompressedImage"
#: Image encodings read, with their channels and whether those are in BGR order.
RAW_ENCODINGS: Final[dict[str, tuple[int, bool]]] = {
    "rgb8": (3, False),
    "bgr8": (3, True),
    "8UC3": (3, True),  # OpenCV's default channel order
    "rgba8": (4, False),
    "bgra8": (4, True),
    "mono8": (1, False),
}
DEPTH_ENCODINGS: Final[tuple[str, ...]] = ("16UC1", "mono16", "32FC1")
COMPRESSED_FORMATS: Final[tuple[str, ...]] = ("jpeg", "jpg", "png")
READABLE: Final[str] = (
    f"readable: Image encodings {', '.join(RAW_ENCODINGS)} and CompressedImage {'/'.join(COMPRESSED_FORMATS)}"
)


def encoding_problem(message: Any, msgtype: str) -> str | None:
    """What makes an image message unreadable (`encoding '16UC1' (…)`), or None when it is readable."""
    if msgtype == IMAGE:
        encoding = str(message.encoding)
        if encoding in RAW_ENCODINGS:
            return None
        if encoding in DEPTH_ENCODINGS:
            return f"encoding {encoding!r} (a depth image, not a colour camera)"
        return f"encoding {encoding!r}"
    form = str(message.format).lower()
    if "compresseddepth" in form:
        return f"CompressedImage format {message.format!r} (a depth image, not a colour camera)"
    if any(name in form for name in COMPRESSED_FORMATS):
        return None
    return f"CompressedImage format {message.format!r}"


def to_rgb(message: Any, msgtype: str, *, where: str) -> np.ndarray:
    """A readable Image or CompressedImage message (`RAW_ENCODINGS`, JPEG, PNG) as (H, W, 3) uint8 RGB."""
    problem = encoding_problem(message, msgtype)
    if problem is not None:
        raise DataError(f"{where}: {problem} is not readable")
    if msgtype == COMPRESSED:
        return decode_image(bytes(message.data), source=where)
    height, width, step = int(message.height), int(message.width), int(message.step)
    check_frame_size(width, height, source=where)
    channels, bgr = RAW_ENCODINGS[str(message.encoding)]
    data = np.asarray(message.data, dtype=np.uint8)
    if step < width * channels or data.size < height * step:
        raise DataError(
            f"{where}: {height}×{width} {message.encoding} needs {height * width * channels} bytes"
        )
    rows = data[: height * step].reshape(height, step)[:, : width * channels]
    image = rows.reshape(height, width, channels)
    if channels == 1:
        return np.ascontiguousarray(np.repeat(image, 3, axis=2))
    return np.ascontiguousarray(image[:, :, 2::-1] if bgr else image[:, :, :3])
