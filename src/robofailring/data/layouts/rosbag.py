"""ROS bags: a ROS 2 bag folder (`metadata.yaml` + `.mcap` or `.db3`), a bare `.mcap` or a ROS 1 `.bag` file per episode.

Read with `rosbags` (pure Python, both ROS 2 storage formats; a `.mcap` file without its
`metadata.yaml` opens alone). Each `sensor_msgs/msg/Image` or `sensor_msgs/msg/CompressedImage`
topic is a view named by its topic (`/cam_front/image_raw`). Views are put on one timeline: the
slowest topic's (the one with the fewest messages, two or more) message log times are the frames, and
frame i of every other topic is its latest message at or before frame i's time (its first message
when none is), so no frame of the slowest topic repeats and a faster topic's frames are the ones seen
then; a topic of one message is a view of one frame, skipped as every view of < 2 frames is.
Opening a bag lists every image message's log time once (nothing kept but the times); a frame reads
its one message on demand, by time, so a long bag is never held whole, and at most `_OPEN_LIMIT`
bags are open at once. Encodings rgb8, bgr8, 8UC3 (OpenCV's BGR), rgba8, bgra8 (alpha dropped),
mono8 and JPEG/PNG compressed images are read; a topic of another (16UC1 or mono16 depth,
compressedDepth, Bayer, …) is listed as not read, naming the topic and its encoding; each
`sensor_msgs/msg/JointState` topic gives signals on the frames' timeline (`rosbag_signals`); other
topics that are not images (/tf) are not camera data and not listed. A bag with no readable image
topic is an error naming what it holds (in a folder of bags: listed as not read, the others read).
The trajectory key is the bag's name
(its folder, or the file's stem); outcome and symbol come from `--labels` (`episode` column = the
bag's name), the task from `--task`, else it is the name of the folder holding the bag.
"""

from __future__ import annotations

import sys
import threading
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.frame_ref import Container, FrameRef, register_reader
from robofailring.data.images import content_digest
from robofailring.data.layouts.folders import visible
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.layouts.ros_messages import COMPRESSED, IMAGE, READABLE, encoding_problem, to_rgb
from robofailring.data.layouts.rosbag_signals import joint_state_signals
from robofailring.data.model import Frame, LazyFrames, Skipped, Trajectory
from robofailring.data.open_files import OpenLimit
from robofailring.errors import DataError, read_error
from robofailring.extras import needs_extra

ROS2_METADATA: Final[str] = "metadata.yaml"
ROS1_SUFFIX: Final[str] = ".bag"
MCAP_SUFFIX: Final[str] = ".mcap"  # a ROS 2 bag's storage file, also read without its metadata.yaml
_OPEN_LIMIT: Final[int] = 8  # bags kept open at once (a folder of bags is read one bag after another)


def is_bag(path: Path) -> bool:
    """A ROS 2 bag folder (it holds `metadata.yaml`), a bare `.mcap` file or a ROS 1 `.bag` file."""
    return (path.is_dir() and (path / ROS2_METADATA).is_file()) or (
        path.is_file() and path.suffix in (ROS1_SUFFIX, MCAP_SUFFIX)
    )


def bag_name(path: Path) -> str:
    """The trajectory key of a bag: its folder's name, or the `.bag`/`.mcap` file's stem."""
    return path.stem if path.is_file() else path.name


@dataclass(frozen=True)
class Topic:
    """One image topic of a bag: its message type and the log time (ns) of each message, in order."""

    name: str
    msgtype: str
    times: np.ndarray  # int64 log times, sorted
    repeat: np.ndarray  # how many earlier messages of the topic share each time (read the n-th one)


class BagFile:
    """One bag: its image topics listed once, one message read and decoded on demand."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._reader: Any = None
        self._topics: dict[str, Topic] | None = None
        self._others: list[str] = []  # non-image topics, `name (type)`
        self._lock = threading.RLock()

    def __repr__(self) -> str:
        return f"BagFile({str(self.path)!r})"

    def __reduce__(self) -> tuple[Any, tuple[Path]]:
        """Pickled as its path: a frame sent to another process (a Ray worker) is read through that
        process's shared reader of the bag (`open_bag`)."""
        return open_bag, (self.path,)

    def _open(self) -> Any:
        with needs_extra("rosbag"):
            from rosbags.highlevel import AnyReader, AnyReaderError
            from rosbags.typesys import Stores, get_typestore

        if self._reader is None:
            reader = AnyReader([self.path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
            try:
                reader.open()
            except (AnyReaderError, OSError, ValueError, KeyError) as error:
                raise read_error(f"cannot read ROS bag {self.path}: {error}", error) from error
            self._reader = reader
            _OPEN.remember(self)
        return self._reader

    @property
    def topics(self) -> dict[str, Topic]:
        """The image topics by name, their messages' log times listed once (no message decoded)."""
        with self._lock:
            if self._topics is None:
                self._topics = self._index()
            return self._topics

    @property
    def other_topics(self) -> list[str]:
        """The topics that are not images, as `name (type)`."""
        _ = self.topics
        return list(self._others)

    def _index(self) -> dict[str, Topic]:
        reader = self._open()
        images = [c for c in reader.connections if c.msgtype in (IMAGE, COMPRESSED)]
        self._others = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections if c not in images})
        stamps: dict[str, list[int]] = {c.topic: [] for c in images}
        types = {c.topic: c.msgtype for c in images}
        if not images:  # rosbags reads every topic when given none
            return {}
        try:
            for connection, stamp, _ in reader.messages(connections=images):
                stamps[connection.topic].append(int(stamp))
        except Exception as error:  # rosbags raises its own reader errors per storage format
            raise DataError(f"cannot read ROS bag {self.path}: {error}") from error
        topics = {}
        for name in sorted(stamps):
            times = np.asarray(sorted(stamps[name]), dtype=np.int64)
            if not len(times):
                continue
            starts = np.searchsorted(times, times, side="left")
            topics[name] = Topic(name, types[name], times, np.arange(len(times)) - starts)
        return topics

    def raw(self, topic: str, index: int) -> tuple[str, bytes]:
        """The message type and serialized bytes of message `index` of `topic`."""
        found = self.topics.get(topic)
        if found is None or not 0 <= index < len(found.times):
            count = 0 if found is None else len(found.times)
            raise DataError(f"ROS bag {self.path} has {count} messages on {topic}; no message {index}")
        stamp, repeat = int(found.times[index]), int(found.repeat[index])
        with self._lock:
            reader = self._open()
            connections = [c for c in reader.connections if c.topic == topic]
            with closing(reader.messages(connections=connections, start=stamp, stop=stamp + 1)) as messages:
                for number, (_, _, data) in enumerate(messages):
                    if number == repeat:
                        return found.msgtype, bytes(data)
        raise DataError(f"ROS bag {self.path}: message {index} of {topic} (at {stamp} ns) is not there")

    def image(self, topic: str, index: int) -> np.ndarray:
        """Message `index` of `topic` as (H, W, 3) uint8 RGB."""
        msgtype, data = self.raw(topic, index)
        with self._lock:
            message = self._open().deserialize(data, msgtype)
        return to_rgb(message, msgtype, where=f"{topic} message {index} of ROS bag {self.path}")

    def problem(self, topic: str) -> str | None:
        """What makes a topic unreadable, judged by its first message (`encoding '16UC1' …`), or None."""
        msgtype, data = self.raw(topic, 0)
        with self._lock:
            message = self._open().deserialize(data, msgtype)
        return encoding_problem(message, msgtype)

    def topics_of(self, msgtype: str) -> list[str]:
        """The names of the topics of one message type (`sensor_msgs/msg/JointState`)."""
        with self._lock:
            return sorted({c.topic for c in self._open().connections if c.msgtype == msgtype})

    def decoded(self, topic: str, *, limit: int | None = None) -> list[tuple[int, Any]]:
        """The messages of a topic (the first `limit`), deserialized, with their log times (ns), in time order."""
        with self._lock:
            reader = self._open()
            connections = [c for c in reader.connections if c.topic == topic]
            try:
                with closing(reader.messages(connections=connections)) as messages:
                    return [
                        (int(stamp), reader.deserialize(data, connection.msgtype))
                        for (connection, stamp, data), _ in zip(
                            messages, range(limit or sys.maxsize), strict=False
                        )
                    ]
            except Exception as error:  # rosbags raises its own reader errors per storage format
                raise DataError(f"cannot read {topic} of ROS bag {self.path}: {error}") from error

    def close(self) -> None:
        with self._lock:
            if self._reader is not None:
                self._reader.close()
            self._reader = None


_OPEN: OpenLimit[BagFile] = OpenLimit(_OPEN_LIMIT)


_BAGS: dict[str, BagFile] = {}


def open_bag(path: Path) -> BagFile:
    """The shared reader of one bag (the frames of a bag share its index)."""
    key = str(Path(path).resolve())
    found = _BAGS.get(key)
    if found is None:
        found = _BAGS[key] = BagFile(Path(path))
    return found


@dataclass(frozen=True)
class BagFrame:
    """Where one frame lives: message `index` of an image topic of a bag."""

    bag: BagFile
    topic: str
    index: int

    def load(self) -> np.ndarray:
        return self.bag.image(self.topic, self.index)

    def content_key(self) -> str:
        """Keyed by the message's serialized bytes (read, not decoded)."""
        msgtype, data = self.bag.raw(self.topic, self.index)
        return content_digest(b"rosbag:" + msgtype.encode() + b":" + data)

    @property
    def reference(self) -> str:
        return str(FrameRef.bag(self.bag.path, self.topic, self.index))


class BagFrames(LazyFrames):
    """One image topic of a bag on the timeline of topic `timeline`: frame i is the topic's latest
    message at or before that topic's message i (its first message when none is)."""

    def __init__(self, bag: BagFile, topic: str, *, timeline: str) -> None:
        self.bag = bag
        self.topic = topic
        own = bag.topics[topic].times
        if topic == timeline:  # every message once, two at one time included
            self._messages = np.arange(len(own))
        else:
            times = bag.topics[timeline].times
            self._messages = np.maximum(np.searchsorted(own, times, side="right") - 1, 0)

    def __len__(self) -> int:
        return len(self._messages)

    def frame(self, index: int) -> Frame:
        return Frame(source=BagFrame(self.bag, self.topic, int(self._messages[index])))

    def __repr__(self) -> str:
        return f"BagFrames({self.bag!r}, {self.topic!r}, {len(self)} frames)"


def _read_bag_message(ref: FrameRef) -> np.ndarray | None:
    """The frame a bag message's reference points at, or None when the bag is not there."""
    if ref.index is None or not is_bag(Path(ref.file)):
        return None
    return open_bag(Path(ref.file)).image(ref.inner, ref.index)


register_reader(Container.BAG, _read_bag_message)


def bag_trajectory(path: Path, *, task: str | None) -> Trajectory:
    """One bag as one trajectory: a view per readable image topic, on the slowest topic's timeline.

    Unreadable image topics (depth, Bayer) are listed as not read; topics that are not images are
    not data of this library and are not listed. A bag with no readable image topic is an error naming
    what it holds. A topic of one message is a view of that one frame (skipped, as every view of < 2
    frames is). The task is `task`, else the name of the folder holding the bag (bags carry no task).
    """
    bag = open_bag(path)
    topics = bag.topics
    problems = {name: bag.problem(name) for name in topics}
    readable = [name for name in topics if problems[name] is None]
    if not readable:
        held = [f"{name} ({problems[name]})" for name in topics] + bag.other_topics
        raise DataError(
            f"ROS bag {path} has no readable image topic ({IMAGE} or {COMPRESSED} with messages; "
            f"{READABLE}); it holds: {', '.join(held) or 'no topics with messages'}"
        )
    # the timeline is the slowest topic of 2+ messages: a topic of one is a view of that one frame,
    # skipped as every view of fewer than 2 frames is (it would cut every view to one frame)
    timed = [name for name in readable if len(topics[name].times) >= 2] or readable
    slowest = min(timed, key=lambda name: len(topics[name].times))
    times = topics[slowest].times
    span = (int(times[-1]) - int(times[0])) / 1e9
    unread = [
        Skipped(path, f"topic {name} has {problem}: not read ({READABLE})", view=name)
        for name, problem in problems.items()
        if problem is not None
    ]
    return Trajectory(
        task=task or path.resolve().parent.name,
        episode=bag_name(path),
        views={name: BagFrames(bag, name, timeline=slowest if name in timed else name) for name in readable},
        source=path,
        fps=(len(times) - 1) / span if span > 0 else None,
        skipped=tuple(unread),  # a bag's other topics (/tf, …) are not camera data left unread
        signals=joint_state_signals(bag, times),
        timestamps=(times - times[0]) / 1e9,
    )


def bag_trajectories(root: Path, *, task: str | None = None) -> Found:
    """A ROS 2 bag folder (one episode), or a folder of bags (one episode each); other entries reported.

    In a folder, a bag that cannot be read (no readable image topic, a broken file) is listed as not
    read, so the others are (`--trajectory` of one of them); a folder where no bag can be is that error.
    """
    root = Path(root)
    if is_bag(root):
        return [bag_trajectory(root, task=task)], []
    found: list[Trajectory] = []
    skipped: list[Skipped] = []
    unreadable: list[DataError] = []
    for entry in visible(root):
        if not is_bag(entry):
            skipped.append(
                Skipped(entry, "not a ROS bag (a folder with metadata.yaml, a .mcap or a .bag file)")
            )
            continue
        try:
            found.append(bag_trajectory(entry, task=task))
        except DataError as error:  # one bag of no camera (depth only) or a broken one: the others are read
            unreadable.append(error)
            skipped.append(Skipped(entry, f"not read: {error}"))
    if unreadable and not found:
        raise unreadable[0]
    names = [t.episode for t in found]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise DataError(
            f"{root} holds two bags named {twice[0]!r} (a folder and a .bag/.mcap file); rename one"
        )
    return found, skipped


def _detect(root: Path) -> bool:
    return is_bag(root) or any(is_bag(entry) for entry in visible(root))


LAYOUT: Final = register(
    Layout(
        name="rosbag",
        detect=_detect,
        read=bag_trajectories,
        help="ROS bags: a ROS 2 bag folder (metadata.yaml + .mcap/.db3), or a folder of them, of .mcap files or of "
        "ROS 1 .bag files",
        listed=10,
        detect_order=60,  # bag files and folders no other layout reads
    )
)
