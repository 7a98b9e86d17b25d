"""The data model: trajectories of multi-view RGB frames, decoded lazily."""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from functools import cached_property
from pathlib import Path
from typing import Final, Protocol, overload

import numpy as np

from robofailring.data.frame_ref import ARRAY_REFERENCE
from robofailring.data.images import as_rgb, content_digest, read_image
from robofailring.data.signals import Signal, SignalValues, read_signal
from robofailring.errors import DataError, read_error


class Outcome(StrEnum):
    """Outcome of a trajectory as decided by the data source (the simulator's goal check)."""

    SUCCESS = "success"
    FAILURE = "failure"


class FrameSource(Protocol):
    """Where a frame that is not an image file lives (a frame of a video), decoded on demand."""

    def load(self) -> np.ndarray: ...

    def content_key(self) -> str: ...

    @property
    def reference(self) -> str: ...


@dataclass(frozen=True)
class Skipped:
    """A folder or file a loader did not read, and why (nothing under a dataset root is dropped silently)."""

    path: Path
    reason: str
    view: str | None = None  # the view it would have been (a bag's depth topic): `--views` naming it says why

    def to_dict(self) -> dict[str, str]:
        return {"path": str(self.path), "reason": self.reason}


@dataclass(frozen=True)
class Frame:
    """One camera image: a file decoded on demand, a frame of a video, or an in-memory array (live robot)."""

    path: Path | None = None
    array: np.ndarray | None = field(default=None, repr=False, compare=False)
    source: FrameSource | None = None

    def __post_init__(self) -> None:
        if sum(x is not None for x in (self.path, self.array, self.source)) != 1:
            raise ValueError("a Frame holds exactly one of path, array or source")

    @classmethod
    def from_array(cls, image: np.ndarray) -> Frame:
        return cls(array=as_rgb(image))

    def load(self) -> np.ndarray:
        """The image as (H, W, 3) uint8 RGB."""
        if self.array is not None:
            return self.array
        if self.source is not None:
            return self.source.load()
        assert self.path is not None
        return read_image(self.path)

    def read_bytes(self) -> bytes | None:
        """The encoded file content, or None for an in-memory frame or a frame of a video."""
        if self.path is None:
            return None
        try:
            return self.path.read_bytes()
        except OSError as error:
            raise read_error(f"cannot read image {self.path}: {error.strerror or error}", error) from error

    def content_key(self) -> str:
        """A digest of the image content (file bytes, array shape and bytes, or the video frame's key)."""
        if self.source is not None:
            return self.source.content_key()
        data = self.read_bytes()
        if data is None:
            assert self.array is not None
            data = str(self.array.shape).encode() + self.array.tobytes()
        return content_digest(data)

    @property
    def reference(self) -> str:
        """A printable reference to the frame (`robofailring.data.frame_ref`: its path, its place in a video, an
        HDF5 dataset or a bag, or '<array>')."""
        if self.source is not None:
            return self.source.reference
        return str(self.path) if self.path is not None else ARRAY_REFERENCE


class LazyFrames(Sequence[Frame]):
    """Frames read on demand (a dataset's rows, a bag's messages, a video's frames): a subclass gives
    `__len__` and `frame(index)` for 0 ≤ index < len; indexing, negative indices and slices are here."""

    def frame(self, index: int) -> Frame:
        raise NotImplementedError

    @property
    def fps(self) -> float | None:
        """The frames' own rate where their source keeps one (a whole video file's container), else None."""
        return None

    @overload
    def __getitem__(self, item: int) -> Frame: ...
    @overload
    def __getitem__(self, item: slice) -> Sequence[Frame]: ...
    def __getitem__(self, item: int | slice) -> Frame | Sequence[Frame]:
        if isinstance(item, slice):
            return [self.frame(i) for i in range(*item.indices(len(self)))]
        count = len(self)
        if item < 0:
            item += count
        if not 0 <= item < count:
            raise IndexError(f"frame {item} of {count}")
        return self.frame(item)


class FrameFiles(LazyFrames):
    """The image files of one folder, in order, held compactly: a large dataset lists hundreds of
    thousands of them (1,000 episodes × 3 views × 200 frames), and a `Frame` with its `Path` each is
    about 500 bytes. Names numbered in one run (`front_0.png` … `front_199.png`, zero-padded or not)
    are kept as their pattern; any others as one string. `Frame`s are made when indexed."""

    def __init__(self, folder: Path, names: Sequence[str]) -> None:
        self.folder = Path(folder)
        self._count = len(names)
        self._pattern = _numbered_run(names)
        self._names = "" if self._pattern is not None else "".join(names)
        self._ends = (
            np.zeros(0, np.int64)
            if self._pattern is not None
            else np.cumsum([len(name) for name in names], dtype=np.int64)
        )

    def __len__(self) -> int:
        return self._count

    def name(self, index: int) -> str:
        if self._pattern is not None:
            prefix, start, width, suffix = self._pattern
            return f"{prefix}{start + index:0{width}d}{suffix}"
        begin = int(self._ends[index - 1]) if index else 0
        return self._names[begin : int(self._ends[index])]

    def frame(self, index: int) -> Frame:
        return Frame(path=self.folder / self.name(index))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, FrameFiles):
            return self.folder == other.folder and list(map(self.name, range(len(self)))) == list(
                map(other.name, range(len(other)))
            )
        return isinstance(other, Sequence) and list(self) == list(other)

    __hash__ = None  # type: ignore[assignment]  # a sequence compared by value, like a list

    def __repr__(self) -> str:
        return f"FrameFiles({str(self.folder)!r}, {len(self)} files)"


_LAST_DIGITS = re.compile(r"(\d+)(?!.*\d)")


def _numbered_run(names: Sequence[str]) -> tuple[str, int, int, str] | None:
    """(prefix, first number, zero-padded width, suffix) when `names` are `prefix<n>suffix` for
    n = first, first + 1, …; else None."""
    match = _LAST_DIGITS.search(names[0]) if names else None
    if match is None:
        return None
    digits = match.group(1)
    prefix, suffix, start = names[0][: match.start()], names[0][match.end() :], int(digits)
    width = len(digits) if digits.startswith("0") else 0
    if any(name != f"{prefix}{start + i:0{width}d}{suffix}" for i, name in enumerate(names)):
        return None
    return prefix, start, width, suffix


@dataclass(frozen=True)
class Trajectory:
    """A replayable episode: task, label, per-view ordered frames and the robot's own signals.

    `symbol` is the FailGen failure symbol (e.g. ``rotation_x_wp1``) or None for a success or an
    unlabelled trajectory; `outcome` is None when the source does not say. `onset_frame` is where a
    failure starts (the simulator's manifest, a labels file's `onset_frame`), None for a success
    and when unknown: alarms before it came before there was anything to see.
    """

    task: str
    episode: str
    views: Mapping[str, Sequence[Frame]]
    symbol: str | None = None
    outcome: Outcome | None = None
    source: Path | None = None
    description: str | None = None  # a labels file's own words for this failure (its grounded sentence)
    fps: float | None = None
    split: str | None = None
    skipped: tuple[Skipped, ...] = ()  # files of this episode that were not read, with the reason
    layout: str | None = None  # the dataset layout it was read from (set by `load_dataset`)
    onset_frame: int | None = None  # a failure's first frame of the fault (its perturbation); None: unknown
    #: the robot's own signals by name (joint state, gripper, actions; `robofailring.data.signals`), read
    #: on demand with `read_signals()`; empty where the layout stores none (videos, image folders)
    signals: Mapping[str, Signal] = field(default_factory=dict, compare=False)
    #: each frame's time in seconds from the episode's start, where the data keeps one (LeRobot's
    #: `timestamp`, a bag's log times); None: frames are evenly spaced at `fps`
    timestamps: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def key(self) -> str:
        """Unique id of the trajectory inside its dataset: ``<task>/<episode>``."""
        return f"{self.task}/{self.episode}"

    @cached_property
    def length(self) -> int:
        """L: the number of synchronised frames (the shortest view bounds it)."""
        counts = [len(frames) for frames in self.views.values()]
        return min(counts) if counts else 0

    @cached_property
    def frame_rate(self) -> float | None:
        """Frames per second: the layout's `fps`, else the first view's own (a video file's container), else
        None. Asked for, not read at load: a video's packets are listed only when its rate is wanted."""
        where = f"{self.source or self.key}"
        if self.fps is not None:
            return check_frame_rate(self.fps, where=where)
        for frames in self.views.values():
            if isinstance(frames, LazyFrames) and (rate := frames.fps) is not None:
                return check_frame_rate(rate, where=where)
        return None

    @property
    def view_names(self) -> list[str]:
        return list(self.views)

    def read_signals(
        self, names: Iterable[str] | None = None
    ) -> tuple[dict[str, SignalValues], list[Skipped]]:
        """Its signals (those `names`, else all) read and checked (`robofailring.data.signals.read_signal`),
        cut to its length; one that cannot be read is listed with the reason, not used."""
        counts = [len(frames) for frames in self.views.values()]
        found: dict[str, SignalValues] = {}
        skipped: list[Skipped] = []
        for name in list(self.signals) if names is None else names:
            signal = self.signals.get(name)
            try:
                if signal is None:
                    raise DataError(f"no signal {name!r} (it has: {', '.join(self.signals) or 'none'})")
                found[name] = read_signal(signal, frames=counts, length=self.length)
            except DataError as error:
                skipped.append(Skipped(self.source or Path(self.key), f"{self.key}: not read: {error}"))
        return found, skipped

    @property
    def is_failure(self) -> bool:
        return self.outcome is Outcome.FAILURE

    @property
    def label(self) -> str:
        """A printable label: the symbol, or the outcome when there is none."""
        if self.symbol:
            return self.symbol
        return self.outcome.value if self.outcome is not None else "unlabelled"


#: The frame rates a recording's `time` timeline takes: one frame per 1,000 s to a 10 kHz sensor (a frame's time
#: in nanoseconds must fit an int64: at 1e-12 fps frame 1 is 1e21 ns, an OverflowError in Rerun)
FPS_RANGE: Final[tuple[float, float]] = (1e-3, 1e4)


def in_fps_range(fps: float) -> bool:
    """Whether `fps` is a finite rate within `FPS_RANGE` (a bool or a string is not a rate)."""
    low, high = FPS_RANGE
    return (
        isinstance(fps, (int, float))
        and not isinstance(fps, bool)
        and math.isfinite(fps)
        and low <= fps <= high
    )


def check_frame_rate(value: object, *, where: str) -> float | None:
    """A dataset's own frame rate (`fps` of a manifest, a video's container, LeRobot's info), None when it
    keeps none; DataError naming `where` when it is not a number within `FPS_RANGE`."""
    if value is None:
        return None
    if not in_fps_range(value):  # type: ignore[arg-type]
        low, high = FPS_RANGE
        raise DataError(
            f"{where}: fps must be a number of frames per second from {low:g} to {high:g}, got {value!r}"
        )
    return float(value)  # type: ignore[arg-type]


def parse_onset_frame(value: object, *, length: int | None, where: str) -> int | None:
    """A failure's onset frame as a manifest or labels file gives it (an integer, `12`, or `"12"`; empty:
    None), checked to be a frame of the trajectory's `length` (None: only ≥ 0): DataError naming `where`
    and the value."""
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    number: int | None = None
    if isinstance(value, int) and not isinstance(value, bool):
        number = value
    elif isinstance(value, str) and re.fullmatch(r"\s*[-+]?[0-9]+\s*", value):
        number = int(value)  # digits only: `3.0`, `1e2` and `0x10` are not frame numbers
    if number is None:
        raise DataError(f"{where}: onset_frame {value!r} is not an integer frame number")
    if number < 0:
        raise DataError(f"{where}: onset_frame {value!r} is negative; frames count from 0")
    if length is not None and number >= length:
        raise DataError(
            f"{where}: onset_frame {value!r} is not a frame of the trajectory (its {length} frames are 0 to "
            f"{length - 1})"
        )
    return number


def frames_from_files(paths: Sequence[Path]) -> tuple[Frame, ...]:
    return tuple(Frame(path=Path(path)) for path in paths)


def load_frames(frames: Sequence[Frame]) -> list[np.ndarray]:
    """Decode a list of frames (for short lists: start/end images, tests)."""
    return [frame.load() for frame in frames]


__all__ = [
    "Frame",
    "FrameFiles",
    "FrameSource",
    "Outcome",
    "Skipped",
    "Trajectory",
    "frames_from_files",
    "load_frames",
    "parse_onset_frame",
    "read_image",
]
