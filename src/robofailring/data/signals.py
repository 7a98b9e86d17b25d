"""The robot's own signals beside its cameras: joint state, gripper, end-effector pose, commanded actions.

A `Signal` is one named per-frame series of a trajectory (LeRobot's `observation.state`, ALOHA's
`qpos`, a ROS `JointState` topic's positions, the simulator's gripper width), read on demand like
frames: a layout gives its name, its kind (`state`, `action` or `other`), the name of each dimension
where the data names them, and a `SignalSource` that reads the values when they are wanted.
`Trajectory.read_signals()` reads every signal of a trajectory as (L, D) float64 rows, one per frame,
checked (`read_signal`): a signal that is not numeric, holds NaN, infinity or a value beyond float32's range, or whose rows match none of the views'
frame counts is not used and is listed as `Skipped` with the reason, never silently dropped.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Final, Protocol

import numpy as np

from robofailring.errors import DataError

#: The most dimensions one signal may have: a flattened (T, 3, 3) rotation is 9, a simulator's whole
#: state vector a few hundred; more is not a robot signal a person reads or a detector should weigh.
MAX_SIGNAL_DIMS: Final[int] = 512
#: The largest magnitude a value may have: a signal memory keeps float32 vectors, and a value beyond it
#: would become infinite there (and its square overflows the normalisation).
FLOAT32_MAX: Final[float] = float(np.finfo(np.float32).max)


class SignalKind(StrEnum):
    """What a signal measures: the robot's state, its commanded action, or anything else it logs."""

    STATE = "state"
    ACTION = "action"
    OTHER = "other"


class SignalSource(Protocol):
    """Where a signal's values live (a parquet column, an HDF5 dataset, a bag's messages), read on demand."""

    def load(self) -> np.ndarray: ...

    @property
    def reference(self) -> str: ...


@dataclass(frozen=True)
class ArraySignal:
    """Values already in memory (the simulator's, a live robot's, a test's)."""

    values: np.ndarray = field(repr=False)
    reference: str = "<array>"

    def load(self) -> np.ndarray:
        return self.values


@dataclass(frozen=True, eq=False)
class Signal:
    """One named per-frame signal of a trajectory: `dims` names each dimension where the data does
    (empty: named `<name>[i]` when read)."""

    name: str
    kind: SignalKind
    source: SignalSource
    dims: tuple[str, ...] = ()

    @classmethod
    def from_array(
        cls, name: str, values: np.ndarray, *, kind: SignalKind = SignalKind.STATE, dims: Sequence[str] = ()
    ) -> Signal:
        return cls(name=name, kind=SignalKind(kind), source=ArraySignal(np.asarray(values)), dims=tuple(dims))

    @property
    def reference(self) -> str:
        return self.source.reference


@dataclass(frozen=True, eq=False)
class SignalValues:
    """A signal read and checked: (L, D) float64 rows, one per frame of the trajectory, and a name per column."""

    name: str
    kind: SignalKind
    dims: tuple[str, ...]
    values: np.ndarray = field(repr=False)

    @property
    def columns(self) -> list[str]:
        """`<signal>/<dimension>` per column: the names recordings and reports use."""
        return [f"{self.name}/{dim}" for dim in self.dims]


def checked_values(raw: object, *, where: str) -> np.ndarray:
    """`raw` as (T, D) float64 rows: a 1-D series is one column, trailing axes are flattened; a value
    that is not numeric, NaN, infinite or beyond float32's range is a DataError naming `where`, the frame
    and the column."""
    try:
        array = np.asarray(raw)
    except (ValueError, TypeError) as error:  # ragged rows
        raise DataError(f"{where}: rows of unequal length ({error})") from error
    if array.dtype.kind not in "biuf":
        raise DataError(f"{where}: values of type {array.dtype} are not numbers")
    if array.ndim == 0 or array.shape[0] == 0:
        raise DataError(f"{where}: no rows")
    values = array.reshape(array.shape[0], -1).astype(np.float64)
    if values.shape[1] == 0 or values.shape[1] > MAX_SIGNAL_DIMS:
        raise DataError(
            f"{where}: {values.shape[1]} dimensions per frame (a signal has 1 to {MAX_SIGNAL_DIMS})"
        )
    bad = ~(np.abs(values) <= FLOAT32_MAX)  # NaN too
    if bad.any():
        row, column = (int(i) for i in np.argwhere(bad)[0])
        raise DataError(
            f"{where}: {int(bad.sum())} value(s) are NaN, infinite or beyond ±{FLOAT32_MAX:.3g} (the first at "
            f"frame {row}, dimension {column}: {values[row, column]})"
        )
    return values


def dimension_names(signal: Signal, width: int, *, where: str) -> tuple[str, ...]:
    """The signal's own names of its `width` dimensions, else `0`, `1`, …; names of another count or
    repeated are a DataError naming `where`."""
    if not signal.dims:
        return tuple(str(i) for i in range(width))
    names = tuple(str(name) for name in signal.dims)
    if len(names) != width:
        raise DataError(f"{where}: {width} dimensions per frame but {len(names)} names ({', '.join(names)})")
    if len(set(names)) != len(names):
        twice = next(name for name in names if names.count(name) > 1)
        raise DataError(f"{where}: dimension name {twice!r} is given twice")
    return names


def read_signal(signal: Signal, *, frames: Iterable[int], length: int) -> SignalValues:
    """One signal read and checked against a trajectory whose views have `frames` frames each and
    whose length (the shortest view) is `length`: rows matching one view's count are cut to `length`."""
    where = f"signal {signal.name!r} ({signal.reference})"
    values = checked_values(signal.source.load(), where=where)
    counts = sorted(set(frames))
    if counts and len(values) not in counts:
        shown = " or ".join(map(str, counts))
        raise DataError(f"{where}: {len(values)} rows, but the trajectory's views have {shown} frames")
    if len(values) < length:
        raise DataError(f"{where}: {len(values)} rows for {length} frames")
    return SignalValues(
        name=signal.name,
        kind=signal.kind,
        dims=dimension_names(signal, values.shape[1], where=where),
        values=values[:length],
    )


def kind_of(name: str) -> SignalKind:
    """A signal's kind from its name as layouts spell it: `action`, `actions`, `action.*` and `*_action`
    are commanded actions; `observation.*`, `obs/*`, `qpos`, `qvel`, `effort`, joint and pose names are state."""
    lowered = name.lower()
    head = lowered.replace("/", ".").split(".")[0]
    if head in ("action", "actions") or lowered.endswith(("_action", ".action", "/action")):
        return SignalKind.ACTION
    if head in ("observation", "obs", "state", "states") or any(
        word in lowered
        for word in ("qpos", "qvel", "effort", "joint", "gripper", "eef", "ee_", "pose", "position")
    ):
        return SignalKind.STATE
    return SignalKind.OTHER


__all__ = [
    "ArraySignal",
    "Signal",
    "SignalKind",
    "SignalSource",
    "SignalValues",
    "checked_values",
    "dimension_names",
    "kind_of",
    "read_signal",
]
