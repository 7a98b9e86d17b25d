"""A ROS bag's joint states as signals: each `sensor_msgs/msg/JointState` topic gives `<topic>/position`,
`<topic>/velocity` and `<topic>/effort` (those its messages fill), one column per joint name.

A joint state topic runs at its own rate (often 100-500 Hz against a camera's 15-30), so it is put
on the frames' timeline as the cameras are: frame i takes the topic's latest message at or before
frame i's log time (its first message when none is). Messages may list their joints in any order; each
is read in the order of the topic's first message, and a message that lacks one of those joints, or
fills a field with another count of values, is a DataError naming the topic and the message.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Protocol

import numpy as np

from robofailring.data.signals import Signal, SignalKind
from robofailring.errors import DataError

JOINT_STATE: Final[str] = "sensor_msgs/msg/JointState"
FIELDS: Final[tuple[str, ...]] = ("position", "velocity", "effort")


class Bag(Protocol):
    """What this module asks of a bag reader (`layout_rosbag.BagFile`)."""

    @property
    def path(self) -> Path: ...

    def topics_of(self, msgtype: str) -> list[str]: ...

    def decoded(self, topic: str, *, limit: int | None = None) -> list[tuple[int, Any]]: ...


@dataclass(frozen=True, eq=False)
class JointStateSignal:
    """One field of a JointState topic, sampled at the frames' log times (`frame_times`, ns)."""

    bag: Bag
    topic: str
    member: str  # the message's field: position, velocity or effort
    joints: tuple[str, ...]
    frame_times: np.ndarray = field(repr=False)

    def load(self) -> np.ndarray:
        messages = self.bag.decoded(self.topic)
        if not messages:
            raise DataError(f"{self.reference}: the topic has no messages")
        times = np.asarray([stamp for stamp, _ in messages], dtype=np.int64)
        rows = np.stack([self._row(message, number) for number, (_, message) in enumerate(messages)])
        latest = np.maximum(np.searchsorted(times, self.frame_times, side="right") - 1, 0)
        return rows[latest]

    def _row(self, message: Any, number: int) -> np.ndarray:
        names = [str(name) for name in message.name]
        values = np.asarray(getattr(message, self.member), dtype=np.float64).ravel()
        if len(values) != len(names):
            raise DataError(
                f"{self.reference}: message {number} names {len(names)} joints but has {len(values)} "
                f"{self.member} values"
            )
        where = {name: index for index, name in enumerate(names)}
        missing = [joint for joint in self.joints if joint not in where]
        if missing:
            raise DataError(f"{self.reference}: message {number} lacks joint {missing[0]!r}")
        return values[[where[joint] for joint in self.joints]]

    @property
    def reference(self) -> str:
        return f"{self.bag.path}#topic={self.topic}&field={self.member}"


def joint_state_signals(bag: Bag, frame_times: np.ndarray) -> dict[str, Signal]:
    """Every JointState topic's filled fields, named `<topic>/<field>`, with the joints of its first message."""
    found: dict[str, Signal] = {}
    for topic in bag.topics_of(JOINT_STATE):
        messages = bag.decoded(topic, limit=1)
        if not messages:
            continue
        first = messages[0][1]
        joints = tuple(str(name) for name in first.name)
        for name in FIELDS:
            if len(getattr(first, name)):  # a field a driver leaves empty (effort, often) is not a signal
                key = f"{topic}/{name}"
                source = JointStateSignal(bag, topic, name, joints, np.asarray(frame_times, np.int64))
                found[key] = Signal(name=key, kind=SignalKind.STATE, source=source, dims=joints)
    return found
