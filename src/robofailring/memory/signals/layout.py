"""Which of the robot's signals (and which of their dimensions) a task's signal memory is made of:
`--signals auto|none|NAME[:GLOB],…`, the `SignalLayout` it gives, and a run's raw features read by it."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fnmatch import fnmatch
from typing import Any, Final

import numpy as np

from robofailring.data.model import Skipped, Trajectory
from robofailring.data.signals import SignalKind, SignalValues
from robofailring.errors import DataError, MemoryFormatError
from robofailring.memory.signals.derived import NO_FEATURES, SignalFeatures

ACTION_LAGS: Final[tuple[int, ...]] = (0, 2, 4)  # the action window: a_t, a_{t−2}, a_{t−4}
AUTO: Final[str] = "auto"  # every state and action signal every run of a task has
NONE: Final[str] = "none"

Columns = tuple[tuple[str, tuple[str, ...]], ...]  # (signal name, its dimension names) in order


def check_choice(choice: str) -> str:
    """`auto`, `none` or a comma-separated list of signals (`--signals`), each `NAME` (all its
    dimensions) or `NAME:GLOB` (those of its dimensions the glob matches, e.g. `observation.state:gripper*`)."""
    items = [item.strip() for item in str(choice).split(",")]
    if not choice or any(not item or item.startswith(":") or item.endswith(":") for item in items):
        raise ValueError(
            f"--signals takes auto, none or signals separated by commas (NAME or NAME:DIMENSION_GLOB), got {choice!r}"
        )
    return str(choice)


def chosen_signals(choice: str) -> dict[str, list[str]]:
    """`--signals` items by signal name, with their dimension globs (empty: every dimension)."""
    chosen: dict[str, list[str]] = {}
    for item in (item.strip() for item in choice.split(",")):
        name, colon, glob = item.rpartition(":") if ":" in item else (item, "", "")
        chosen.setdefault(name if colon else item, []).extend([glob] if colon else [])
    return chosen


@dataclass(frozen=True)
class SignalLayout:
    """Which signals a task's vectors are made of, in order: its state signals and its action signals."""

    state: Columns
    action: Columns
    # each signal's own dimensions where only some of them are used (`NAME:GLOB`): a live step's vector
    # is the whole signal, and the used ones are taken from it
    full: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    # the features derived from them and added to the state (robofailring.memory.signals.derived); () for
    # a memory built before they existed
    derived: tuple[str, ...] = ()

    def select(self, name: str, dims: Sequence[str], values: np.ndarray, where: str) -> np.ndarray:
        """A signal's (L, D) rows with its own dimension names `dims`, cut to the layout's dimensions; a
        signal of other dimensions than the task's runs have (wider, narrower, renamed) is a DataError naming
        them, never cut to fit."""
        wanted = dict((*self.state, *self.action))[name]
        own = self.full.get(name, wanted)  # the whole signal the task's runs have
        if set(dims) != set(own):
            raise DataError(
                f"{where}: signal {name!r} has {len(dims)} dimension(s) ({_shown(dims)}), but the task's runs "
                f"have {len(own)} ({_shown(own)})"
            )
        if tuple(dims) == wanted:
            return values
        return values[:, [list(dims).index(dim) for dim in wanted]]

    @property
    def names(self) -> list[str]:
        return [name for name, _ in (*self.state, *self.action)]

    @property
    def widths(self) -> tuple[int, int]:
        return sum(len(d) for _, d in self.state), sum(len(d) for _, d in self.action)

    def raw_columns(self) -> list[str]:
        """The state and action dimensions' names (`gripper_width/width`, …), in the raw features' order."""
        return [f"{name}/{dim}" for name, dims in (*self.state, *self.action) for dim in dims]

    def columns(self, derived: Sequence[str] = ()) -> list[str]:
        """What each element of a vector is, for explanations (`gripper_width/width (change)`, …); `derived`:
        the names of the derived columns the task's vectors add to the state (they are 0 at the start, so
        their change since then is their value)."""
        state = [f"{name}/{dim}" for name, dims in self.state for dim in dims]
        action = [f"{name}/{dim}" for name, dims in self.action for dim in dims]
        return [
            *(f"{c} (at the start)" for c in (*state, *derived)),
            *(f"{c} (change since the start)" for c in state),
            *derived,
            *(
                f"{c} (commanded{f', {lag} frames before' if lag else ''})"
                for lag in ACTION_LAGS
                for c in action
            ),
            "frame (time)",
        ]

    def features(self, values: Mapping[str, np.ndarray], length: int) -> np.ndarray:
        """Raw per-frame features f_t = [state ‖ action ‖ t] from each signal's (L, D) rows."""
        parts = [np.asarray(values[name], np.float64).reshape(length, -1) for name in self.names]
        return np.concatenate([*parts, np.arange(length, dtype=np.float64)[:, None]], axis=1)

    def to_dict(self) -> dict[str, Any]:
        found: dict[str, Any] = {
            kind: [[name, list(dims)] for name, dims in columns] for kind, columns in self._kinds()
        }
        full = {"full": {name: list(dims) for name, dims in self.full.items()}} if self.full else {}
        return found | full | ({"derived": list(self.derived)} if self.derived else {})

    def _kinds(self) -> tuple[tuple[str, Columns], ...]:
        return (("state", self.state), ("action", self.action))

    @classmethod
    def parse(cls, section: Any, where: str) -> SignalLayout:
        try:
            return cls(
                **{
                    kind: tuple((str(name), tuple(str(d) for d in dims)) for name, dims in section[kind])
                    for kind in ("state", "action")
                },
                full={str(n): tuple(str(d) for d in dims) for n, dims in (section.get("full") or {}).items()},
                derived=SignalFeatures.of_kinds(section.get("derived") or []).kinds,
            )
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            raise MemoryFormatError(f"{where}: bad signal layout {section!r} ({error!r})") from error


def read_features(trajectory: Trajectory, layout: SignalLayout) -> np.ndarray:
    """The trajectory's raw features for `layout`, or DataError naming what it lacks or cannot read."""
    found, skipped = trajectory.read_signals(layout.names)
    if skipped:
        raise DataError(skipped[0].reason)
    values = {
        name: layout.select(name, found[name].dims, found[name].values, trajectory.key)
        for name in layout.names
    }
    return layout.features(values, trajectory.length)


def choose_layout(
    trajectories: Sequence[Trajectory], choice: str, features: SignalFeatures = NO_FEATURES
) -> tuple[SignalLayout | None, list[Skipped]]:
    """The layout of one task's runs for `choice`, decided by all of them, not by whichever comes first:
    `auto` takes every state and action signal at least half of the runs with signals have, names take those
    signals, whatever their kind (`other` counts as state); each signal has the dimensions most of the runs
    that read it well have. A run whose signal is missing, unreadable (NaN, infinite, no rows, not numbers) or
    of other dimensions is skipped when the memory is built, with the reason, and the others keep the signal;
    a signal `auto` found that no run reads well is left out, each run's reason listed (the second value).
    `features` (`--signal-features`) are derived from them. None: no signals to use."""
    if choice == NONE:
        return None, []
    runs = [t for t in trajectories if t.signals]
    if not runs:
        return None, []
    globs = _candidates(runs) if choice == AUTO else chosen_signals(choice)
    voted, unread = _vote(runs, list(globs))
    if choice != AUTO:
        absent = next((name for name in globs if name not in voted), None)
        if absent is not None:
            first = (unread.get(absent) or runs[0].read_signals([absent])[1])[0]
            raise DataError(f"--signals {choice}: {first.reason}")
    dims: dict[str, tuple[str, ...]] = {}
    for name, signal in voted.items():
        dims[name] = tuple(
            d for d in signal.dims if not globs[name] or any(fnmatch(d, g) for g in globs[name])
        )
        if not dims[name]:
            raise DataError(
                f"--signals {choice}: no dimension of {name!r} matches {', '.join(globs[name])} (it has: "
                f"{', '.join(signal.dims)})"
            )
    state = tuple((n, dims[n]) for n, v in voted.items() if v.kind is not SignalKind.ACTION)
    action = tuple((n, dims[n]) for n, v in voted.items() if v.kind is SignalKind.ACTION)
    full = {n: v.dims for n, v in voted.items() if dims[n] != v.dims}
    dropped = [  # those that were read well elsewhere are listed when the memory is built
        Skipped(each.path, f"signal not used: {each.reason} (no run of the task reads it well: left out)")
        for name, skipped in unread.items()
        if name not in voted
        for each in skipped
    ]
    if not (state or action):
        return None, dropped
    return SignalLayout(state=state, action=action, full=full, derived=features.kinds), dropped


def _candidates(runs: Sequence[Trajectory]) -> dict[str, list[str]]:
    """`auto`'s signals: the state and action signals at least half of `runs` have, in the order they come."""
    counts = Counter(
        name
        for run in runs
        for name, signal in run.signals.items()
        if signal.kind in (SignalKind.STATE, SignalKind.ACTION)
    )
    return {name: [] for name, count in counts.items() if 2 * count >= len(runs)}


def _vote(
    runs: Sequence[Trajectory], names: Sequence[str]
) -> tuple[dict[str, SignalValues], dict[str, list[Skipped]]]:
    """Each of `names` as most of the `runs` that read it well have it (its dimensions; a tie: the first
    run's), left out where no run reads it well, and what could not be read: one run's bad value does not
    decide for the others."""
    read: dict[str, list[SignalValues]] = {name: [] for name in names}
    unread: dict[str, list[Skipped]] = {name: [] for name in names}
    for run in runs:
        for name in (name for name in names if name in run.signals):
            found, skipped = run.read_signals([name])
            read[name] += found.values()
            unread[name] += skipped
    voted = {}
    for name, good in read.items():
        if good:
            common = Counter(values.dims for values in good).most_common(1)[0][0]
            voted[name] = next(values for values in good if values.dims == common)
    return voted, unread


def _shown(dims: Sequence[str]) -> str:
    return ", ".join(dims) if len(dims) <= 8 else f"{', '.join(dims[:8])}, …"
