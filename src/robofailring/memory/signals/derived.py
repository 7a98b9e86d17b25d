"""Features derived from a run's raw signal features, causally (frame t reads frames ≤ t): what the robot did
rather than where it was (`--signal-features`, docs/signals.md).

- `change`: each state and action dimension's change over the last frame, x_t − x_{t−1} (0 at the start);
- `events`: for each **step-like** dimension (one that jumps now and then and otherwise holds, such as a
  gripper's width or command), how many jumps it has made so far and how many frames ago the last one was
  (t while it has made none). A jump is a one-frame change over `JUMP_SHARE` of the dimension's usual range
  within a success run (the median over the task's success runs); a dimension is step-like when it jumps
  in at least one and at most `STEP_SHARE` of the success runs' frames. Which dimensions and their
  tolerances are fitted per task on its success runs and kept with the memory.

They are added to the state features, so a frame's vector says how far into its gripper events a run is,
whether it closed or reopened, and how fast it moves: closing on nothing, reopening mid-carry or never
closing are distances to the success frames, where absolute positions move with where objects were placed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final

import numpy as np

from robofailring.errors import MemoryFormatError

CHANGE: Final[str] = "change"
EVENTS: Final[str] = "events"
KINDS: Final[tuple[str, ...]] = (CHANGE, EVENTS)
NONE: Final[str] = "none"
JUMP_SHARE: Final[float] = 0.05  # a jump: a one-frame change over this share of the usual in-run range …
STEP_SHARE: Final[float] = 0.25  # … and a step-like dimension jumps in at most this share of the frames


@dataclass(frozen=True)
class SignalFeatures:
    """The derived features a signal memory adds (`--signal-features`), parsed once where they are given: their
    kinds in the order `KINDS` lists them (() for `none`), and the text they were given as, which manifests keep
    and memory-info shows (two texts of the same kinds are equal)."""

    kinds: tuple[str, ...] = ()
    text: str = field(default=NONE, compare=False)

    @classmethod
    def parse(cls, text: str) -> SignalFeatures:
        """`none` or kinds separated by commas (`change`, `events`); ValueError naming the choices otherwise."""
        items = [item.strip() for item in str(text).split(",")]
        if items == [NONE]:
            return cls((), str(text))
        if any(item not in KINDS for item in items):
            raise ValueError(
                f"--signal-features takes none or {', '.join(KINDS)} separated by commas, got {text!r}"
            )
        return cls(tuple(kind for kind in KINDS if kind in items), str(text))

    @classmethod
    def of_kinds(cls, kinds: Sequence[object]) -> SignalFeatures:
        """The features of a list of kinds (a stored layout's `derived`); ValueError for one not in `KINDS`."""
        given = [] if list(kinds) == [NONE] else list(kinds)
        unknown = [kind for kind in given if kind not in KINDS]
        if unknown:
            raise ValueError(f"derived signal features are {', '.join(KINDS)}, not {unknown!r}")
        ordered = tuple(kind for kind in KINDS if kind in given)
        return cls(ordered, ",".join(ordered) or NONE)

    def __str__(self) -> str:
        return self.text


# the benchmarks' best (docs/signals.md, "In a memory")
DEFAULT_FEATURES: Final[SignalFeatures] = SignalFeatures.parse(f"{CHANGE},{EVENTS}")
NO_FEATURES: Final[SignalFeatures] = SignalFeatures.parse(NONE)  # a memory from before derived features


@dataclass(frozen=True)
class Derivation:
    """One task's derived features: the kinds, and for `events` its step-like columns (of [state ‖ action])
    with their jump tolerances."""

    kinds: tuple[str, ...]
    columns: int  # the raw state and action columns it reads (the features' last column, t, is not read)
    steps: np.ndarray  # (S,) int: the step-like columns
    tolerance: np.ndarray  # (S,) their jump tolerances

    @classmethod
    def fit(cls, kinds: Sequence[str], columns: int, successes: Sequence[np.ndarray]) -> Derivation:
        """The derivation of `kinds` for raw features [state ‖ action ‖ t] with `columns` state and action
        columns, its step-like columns found on the success runs' features (each (L, columns + 1))."""
        steps, tolerance = np.zeros(0, np.int64), np.zeros(0)
        runs = [np.asarray(run, np.float64)[:, :columns] for run in successes]
        if EVENTS in kinds and runs:
            usual = np.median([run.max(axis=0) - run.min(axis=0) for run in runs], axis=0)
            jumps = JUMP_SHARE * usual
            moved = np.concatenate([np.abs(np.diff(run, axis=0)) > jumps for run in runs])
            share = moved.mean(axis=0) if len(moved) else np.zeros(columns)
            steps = np.flatnonzero((jumps > 0) & (share > 0) & (share <= STEP_SHARE))
            tolerance = jumps[steps]
        return cls(tuple(kinds), columns, steps.astype(np.int64), tolerance.astype(np.float64))

    @property
    def width(self) -> int:
        """How many columns it adds."""
        return (self.columns if CHANGE in self.kinds else 0) + (
            2 * len(self.steps) if EVENTS in self.kinds else 0
        )

    def names(self, columns: Sequence[str]) -> list[str]:
        """What each added column is, from the names of the raw state and action columns."""
        stepped = [columns[i] for i in self.steps]
        return [
            *((f"{c} (change over the last frame)" for c in columns) if CHANGE in self.kinds else ()),
            *((f"{c} (jumps so far)" for c in stepped) if EVENTS in self.kinds else ()),
            *((f"{c} (frames since its last jump)" for c in stepped) if EVENTS in self.kinds else ()),
        ]

    def added(self, features: np.ndarray) -> np.ndarray:
        """The (L, width) derived columns of one run's raw features (L, columns + 1), frame t from frames ≤ t."""
        raw = np.asarray(features, np.float64)[:, : self.columns]
        change = np.concatenate([np.zeros_like(raw[:1]), np.diff(raw, axis=0)])
        parts = [change] if CHANGE in self.kinds else []
        if EVENTS in self.kinds:
            moved = np.abs(change[:, self.steps]) > self.tolerance
            frames = np.arange(len(raw))[:, None]
            last = np.maximum.accumulate(np.where(moved, frames, 0), axis=0)
            parts += [np.cumsum(moved, axis=0, dtype=np.float64), (frames - last).astype(np.float64)]
        return np.concatenate(parts, axis=1) if parts else np.zeros((len(raw), 0))

    def arrays(self, key: str) -> dict[str, np.ndarray]:
        """What the memory's `signals.npz` keeps of it, under the task's `key`."""
        return {f"{key}_steps": self.steps, f"{key}_step_tolerance": self.tolerance}

    @classmethod
    def read(
        cls, kinds: Sequence[str], columns: int, arrays: dict[str, np.ndarray], key: str, where: str
    ) -> Derivation:
        """What `arrays` wrote, checked against the layout's `columns`."""
        try:
            steps = np.asarray(arrays[f"{key}_steps"], np.int64)
            tolerance = np.asarray(arrays[f"{key}_step_tolerance"], np.float64)
        except KeyError as error:
            raise MemoryFormatError(f"{where}: the signal memory lacks {error} (a damaged file?)") from error
        if (
            steps.shape != tolerance.shape
            or steps.ndim != 1
            or (len(steps) and (steps.min() < 0 or steps.max() >= columns))
        ):
            raise MemoryFormatError(
                f"{where}: task key {key!r} has step-like columns {steps.tolist()} for {columns} columns"
            )
        return cls(tuple(kinds), columns, steps, tolerance)


@dataclass(frozen=True)
class RunningDerivation:
    """A derivation fed one frame at a time, as a live session sees them: each frame's derived columns, equal
    to `Derivation.added`'s row for it, from constant state (the last frame's values and, per step-like
    column, its jumps so far and its last jump), so the thousandth step costs what the tenth does."""

    derivation: Derivation
    frames: int = 0  # how many frames it has seen
    previous: np.ndarray | None = None  # the last frame's raw state and action columns
    jumps: np.ndarray | None = None  # per step-like column: its jumps so far …
    last: np.ndarray | None = None  # … and the frame of its last jump (0 while none)

    def add(self, features: np.ndarray) -> tuple[np.ndarray, RunningDerivation]:
        """The (width,) derived columns of the next frame's raw features (columns + 1,), and the running
        derivation that has seen it (this one is left as it was)."""
        derivation = self.derivation
        raw = np.array(features, np.float64)[: derivation.columns]
        change = raw - self.previous if self.previous is not None else np.zeros_like(raw)
        jumps = self.jumps if self.jumps is not None else np.zeros(len(derivation.steps))
        last = self.last if self.last is not None else np.zeros(len(derivation.steps))
        parts = [change] if CHANGE in derivation.kinds else []
        if EVENTS in derivation.kinds:
            moved = np.abs(change[derivation.steps]) > derivation.tolerance
            jumps, last = jumps + moved, np.where(moved, self.frames, last)
            parts += [jumps, self.frames - last]
        added = np.concatenate(parts) if parts else np.zeros(0)
        return added, RunningDerivation(derivation, self.frames + 1, raw, jumps, last)
