"""Small ROS bags written with rosbags' own writers (ROS 1 `.bag`; ROS 2 with MCAP or SQLite storage).

Each image topic is written as `sensor_msgs/msg/Image` in its encoding (rgb8, bgr8, 8UC3 as BGR,
rgba8, bgra8 with an opaque alpha, mono8, or any other name, e.g. 16UC1, written as two bytes a
pixel) or as a `sensor_msgs/msg/CompressedImage`: JPEG/PNG (`jpeg` / `png`), or a depth topic's
`compressedDepth` (a 16-bit PNG behind image_transport's format string). Frames come from
`FrameFn(topic number, t)` as RGB; mono8 topics store their first channel. Messages of a topic are
0.1 s apart unless `timing` gives its start offset and period; log time = header stamp.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

FrameFn = Callable[[int, int], np.ndarray]  # (topic number, t) -> RGB
Topics = Sequence[tuple[str, str]]  # (topic, encoding: rgb8 | bgr8 | mono8 | jpeg | png | other)
START_NS = 1_700_000_000 * 10**9
PERIOD_NS = 100_000_000


def stored(image: np.ndarray, encoding: str) -> np.ndarray:
    """What a topic of this encoding holds of an RGB frame, read back as RGB (exact for raw ones)."""
    if encoding == "mono8":
        return np.repeat(image[:, :, :1], 3, axis=2)
    return image


def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


COMPRESSED_FORMATS = {"jpeg": "jpeg", "png": "png", "compressedDepth": "16UC1; compressedDepth png"}


def _message(store: Any, image: np.ndarray, encoding: str, stamp: int) -> tuple[str, Any]:
    types = store.types
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="cam"
    )
    height, width = image.shape[:2]
    if encoding in COMPRESSED_FORMATS:
        if encoding == "compressedDepth":  # image_transport's 12-byte header, then a 16-bit PNG
            ok, data = cv2.imencode(".png", image[:, :, 0].astype(np.uint16) * 64)
            data = np.concatenate([np.zeros(12, np.uint8), data.ravel()])
        else:
            ok, data = cv2.imencode(f".{'jpg' if encoding == 'jpeg' else 'png'}", image[:, :, ::-1])
        assert ok
        message = types["sensor_msgs/msg/CompressedImage"](
            header=header, format=COMPRESSED_FORMATS[encoding], data=np.asarray(data, dtype=np.uint8).ravel()
        )
        return "sensor_msgs/msg/CompressedImage", message
    opaque = np.full((height, width, 1), 255, np.uint8)
    if encoding == "rgb8":
        pixels = image
    elif encoding in ("bgr8", "8UC3"):
        pixels = image[:, :, ::-1]
    elif encoding == "rgba8":
        pixels = np.concatenate([image, opaque], axis=2)
    elif encoding == "bgra8":
        pixels = np.concatenate([image[:, :, ::-1], opaque], axis=2)
    elif encoding == "mono8":
        pixels = image[:, :, :1]
    else:  # another encoding (16UC1, …): two bytes a pixel, whatever they hold
        pixels = np.repeat(image[:, :, :1], 2, axis=2)
    data = np.ascontiguousarray(pixels, dtype=np.uint8).ravel()
    message = types["sensor_msgs/msg/Image"](
        header=header,
        height=height,
        width=width,
        encoding=encoding,
        is_bigendian=0,
        step=width * pixels.shape[2],
        data=data,
    )
    return "sensor_msgs/msg/Image", message


def write_bag(
    path: Path,
    *,
    kind: str,
    topics: Topics,
    frames: FrameFn,
    count: int,
    extra_topics: Sequence[str] = (),
    timing: dict[str, tuple[int, int]] | None = None,
    joint_states: tuple[str, int] | None = None,
) -> Path:
    """A bag at `path` (`kind`: ros1 → a `.bag` file; mcap / sqlite3 → a ROS 2 bag folder; mcap_file →
    a bare `.mcap` file, the storage file of a ROS 2 bag without its `metadata.yaml`).

    `extra_topics` are `std_msgs/msg/String` topics with one message each (not images). `joint_states`
    (topic, period in ns) adds a `sensor_msgs/msg/JointState` topic from START_NS every period over the
    same span: joints JOINTS (listed reversed in every odd message), positions `joint_position(n, j)` of
    message n, velocities j, no efforts. A topic of
    `timing` (topic → (start offset, period) in ns) has its messages from START_NS + offset every
    period while before START_NS + count periods of 0.1 s; the others have `count` messages 0.1 s apart.
    """
    if kind == "mcap_file":
        folder = write_bag(
            path.with_suffix(".tmp"), kind="mcap", topics=topics, frames=frames, count=count,
            extra_topics=extra_topics, timing=timing, joint_states=joint_states,
        )  # fmt: skip
        next(folder.glob("*.mcap")).rename(path)
        shutil.rmtree(folder)
        return path
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    store = _typestore()
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "ros1":
        writer: Any = Writer1(path)
        serialize = store.serialize_ros1
    else:
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=9, storage_plugin=plugin)
        serialize = store.serialize_cdr
    with writer:
        connections = []
        for topic, encoding in topics:
            msgtype = (
                "sensor_msgs/msg/CompressedImage"
                if encoding in COMPRESSED_FORMATS
                else "sensor_msgs/msg/Image"
            )
            connections.append(writer.add_connection(topic, msgtype, typestore=store))
        for name in extra_topics:
            text = writer.add_connection(name, "std_msgs/msg/String", typestore=store)
            string = store.types["std_msgs/msg/String"](data="hello")
            writer.write(text, START_NS, serialize(string, "std_msgs/msg/String"))
        events = []  # (log time, topic number, message number of the topic)
        for number, (topic, _) in enumerate(topics):
            offset, period = (timing or {}).get(topic, (0, PERIOD_NS))
            stamps = range(START_NS + offset, START_NS + count * PERIOD_NS, period)
            events += [(stamp, number, t) for t, stamp in enumerate(stamps)]
        for stamp, number, t in sorted(events):
            msgtype, message = _message(store, frames(number, t), topics[number][1], stamp)
            writer.write(connections[number], stamp, serialize(message, msgtype))
        if joint_states is not None:
            topic, period = joint_states
            joints = writer.add_connection(topic, JOINT_STATE, typestore=store)
            for n, stamp in enumerate(range(START_NS, START_NS + count * PERIOD_NS, period)):
                message = _joint_state(store, n, stamp)
                writer.write(joints, stamp, serialize(message, JOINT_STATE))
    return path


JOINT_STATE = "sensor_msgs/msg/JointState"
JOINTS = ("shoulder", "elbow", "wrist")


def joint_position(n: int, joint: int) -> float:
    return 0.1 * n + joint


def _joint_state(store: Any, n: int, stamp: int) -> Any:
    types = store.types
    order = list(range(len(JOINTS)))[:: -1 if n % 2 else 1]
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="base"
    )
    return types[JOINT_STATE](
        header=header,
        name=[JOINTS[j] for j in order],
        position=np.asarray([joint_position(n, j) for j in order], np.float64),
        velocity=np.asarray(order, np.float64),
        effort=np.zeros(0, np.float64),
    )
