"""Which elements of a task's signal vectors separate its failures from its successes, chosen from the task's own
training runs (`--signals auto`, docs/signals.md "Chosen from the data").

A task's paired vectors (`robofailring.memory.signals.memory`) are cut into **groups**, one per raw dimension's
value (its change since the start, or a commanded action's window), its change over the last frame, its events
(jumps so far and frames since the last) and the moment (the frame number). Each held-out training run is
scored against the task's other runs as the detector scores a run (its peak contrast C = S⁻ − S⁺ over its
frames, each S = exp(−d²/n) to the nearest failure or success entry of another run); the groups that separate
on their own are added one at a time while the cross-validated separation of failure runs from success runs (the AUC of their peaks, a
margin breaking ties) grows. The moment is then weighted (0, 1, 2 or 4) so that a frame is compared with
successes at the same phase of the task when that separates better. Nothing here knows a joint or a gripper
by name: what separates is measured.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final, Protocol

import numpy as np

from robofailring.data.model import Trajectory
from robofailring.errors import MemoryFormatError
from robofailring.memory.signals.derived import EVENTS, Derivation
from robofailring.memory.signals.layout import SignalLayout

MIN_RUNS: Final[int] = 4  # failure and success runs a task needs (each) for its dimensions to be chosen
MAX_GROUPS: Final[int] = 12  # groups chosen at most
MIN_GAIN: Final[float] = 0.01  # a group is added only when the criterion grows by more (about 2 of 200 pairs)
# a choice is kept only when its held-out AUC exceeds every dimension's by this much: it is chosen on the runs the
# thresholds are then calibrated on, so a small gain there is mostly theirs (docs/signals.md)
MIN_LIFT: Final[float] = 0.1
MIN_ALONE: Final[float] = 0.6  # a group is a candidate only when its held-out AUC alone reaches this
MAX_FRAMES: Final[int] = 700  # frames a fit compares (runs' frames thinned evenly beyond)
PHASE_WEIGHTS: Final[tuple[float, ...]] = (0.0, 1.0, 2.0, 4.0)  # the moment's weights tried
TIME: Final[str] = "frame (time)"


@dataclass(frozen=True)
class Group:
    """Elements of a task's paired vector that belong together (one dimension's value, change or events)."""

    name: str
    columns: tuple[int, ...]


@dataclass(frozen=True)
class Chosen:
    """One chosen group with why: its cross-validated AUC alone and the set's once it was added."""

    name: str
    auc_alone: float
    auc_with: float


@dataclass(frozen=True)
class Selection:
    """The elements a task's vectors keep (`columns` of the full paired vector), each weighted, and why."""

    columns: np.ndarray  # (K,) int, ascending
    weights: np.ndarray  # (K,) float
    chosen: tuple[Chosen, ...]
    phase_weight: float  # the moment's weight (0: left out)
    auc: float  # the cross-validated AUC of the training runs' peaks with these elements
    auc_all: float  # … and with every element
    runs: tuple[int, int]  # (failure, success) training runs it was chosen on

    def apply(self, vectors: np.ndarray) -> np.ndarray:
        """The kept, weighted elements of full paired `vectors` (N, W)."""
        return (np.asarray(vectors)[:, self.columns] * self.weights).astype(np.float32)

    def names(self, columns: Sequence[str]) -> list[str]:
        """The kept elements' names from the full vector's `columns`."""
        return [columns[i] for i in self.columns]

    def describe(self) -> dict[str, Any]:
        """The manifest's record: what was chosen, with what weight, and why."""
        failures, successes = self.runs
        return {
            "chosen": [
                {"group": c.name, "auc_alone": round(c.auc_alone, 4), "auc_with": round(c.auc_with, 4)}
                for c in self.chosen
            ],
            "phase_weight": self.phase_weight,
            "elements": len(self.columns),
            "runs": list(self.runs),
            "auc": round(self.auc, 4),
            "auc_all": round(self.auc_all, 4),
            "why": (
                f"cross-validated over {failures} failure and {successes} success training runs (each held out "
                f"in turn): AUC of peak contrast {self.auc:.3f} with these, {self.auc_all:.3f} with every dimension"
            ),
        }

    def arrays(self, key: str) -> dict[str, np.ndarray]:
        return {f"{key}_selected": self.columns, f"{key}_selected_weights": self.weights}

    @classmethod
    def read(
        cls, described: Mapping[str, Any], arrays: dict[str, np.ndarray], key: str, width: int, where: str
    ) -> Selection:
        """What `arrays` and `describe` wrote, checked against the full vector's `width`."""
        try:
            columns = np.asarray(arrays[f"{key}_selected"], np.int64)
            weights = np.asarray(arrays[f"{key}_selected_weights"], np.float64)
            chosen = tuple(
                Chosen(str(c["group"]), float(c["auc_alone"]), float(c["auc_with"]))
                for c in described["chosen"]
            )
            phase, auc, auc_all = (float(described[k]) for k in ("phase_weight", "auc", "auc_all"))
            failures, successes = (int(n) for n in described["runs"])
        except (KeyError, TypeError, ValueError) as error:
            raise MemoryFormatError(
                f"{where}: task key {key!r} has a bad signal selection ({error!r})"
            ) from error
        if columns.ndim != 1 or columns.shape != weights.shape or not len(columns) or columns.max() >= width:
            raise MemoryFormatError(
                f"{where}: task key {key!r} keeps signal elements {columns.tolist()} of {width}"
            )
        return cls(columns, weights, chosen, phase, auc, auc_all, (failures, successes))


def groups(
    state: Sequence[str], derived: Sequence[str], action: Sequence[str], steps: int, *, start: bool
) -> list[Group]:
    """The groups of a paired vector [start ‖ change ‖ actions at 3 lags ‖ time] whose state is the raw
    columns `state` followed by the `derived` ones (`derived.Derivation.names`: a change per raw state
    and action column, then each of the `steps` step-like columns' jumps and frames since), and whose action
    is the columns `action`; `start`: whether the start state's elements count (a weight above 0)."""
    width = len(state) + len(derived)

    def of(column: int) -> tuple[int, ...]:
        return (column, width + column) if start else (width + column,)

    out = [Group(name, of(i)) for i, name in enumerate(state)]
    out += [
        Group(f"{name} (commanded)", tuple(2 * width + lag * len(action) + a for lag in range(3)))
        for a, name in enumerate(action)
    ]
    changes = len(derived) - 2 * steps
    out += [Group(derived[j], of(len(state) + j)) for j in range(changes)]
    for j in range(steps):
        first, second = len(state) + changes + j, len(state) + changes + steps + j
        name = derived[changes + j].replace(" (jumps so far)", " (events)")
        out.append(Group(name, of(first) + of(second)))
    out.append(Group(TIME, (2 * width + 3 * len(action),)))
    return out


def _auc(failures: np.ndarray, successes: np.ndarray) -> float:
    """P(a failure's peak > a success's), ties counting half."""
    greater = (failures[:, None] > successes[None, :]).mean()
    ties = (failures[:, None] == successes[None, :]).mean()
    return float(greater + 0.5 * ties)


class _Fit:
    """The held-out scoring of one task's training runs for any set of groups."""

    def __init__(self, runs: Sequence[np.ndarray], failure: Sequence[bool], onsets: Sequence[int]) -> None:
        total = sum(len(r) for r in runs)
        stride = max(1, int(np.ceil(total / MAX_FRAMES)))
        frames = [np.arange(0, len(r), stride) for r in runs]
        self.vectors = np.concatenate(
            [np.asarray(r, np.float64)[f] for r, f in zip(runs, frames, strict=True)]
        )
        self.run = np.concatenate([np.full(len(f), i) for i, f in enumerate(frames)])
        self.failed = np.asarray(failure, bool)
        is_failure = self.failed[self.run]
        onset = np.concatenate([np.full(len(f), o) for f, o in zip(frames, onsets, strict=True)])
        at = np.concatenate([f for f in frames])
        self.failure_entries = is_failure & (at >= onset)
        self.success_entries = ~is_failure
        self.other = self.run[:, None] != self.run[None, :]  # an entry of another run than the query's

    def distances(self, group: Group, weight: float = 1.0) -> np.ndarray:
        part = self.vectors[:, list(group.columns)] * weight
        squared = np.einsum("ij,ij->i", part, part)
        return np.maximum(squared[:, None] + squared[None, :] - 2 * part @ part.T, 0.0)

    def score(self, squared: np.ndarray, elements: int) -> tuple[float, float]:
        """(AUC, margin) of the held-out runs' peak contrast for summed squared distances over `elements`."""
        n = max(elements, 1)
        nearest = []
        for entries in (self.failure_entries, self.success_entries):
            allowed = self.other & entries[None, :]
            nearest.append(np.where(allowed, squared, np.inf).min(axis=1))
        contrast = np.exp(-nearest[0] / n) - np.exp(-nearest[1] / n)
        peaks = np.full(len(self.failed), -np.inf)
        np.maximum.at(peaks, self.run, contrast)
        failed, normal = peaks[self.failed], peaks[~self.failed]
        spread = np.sqrt(0.5 * (failed.var() + normal.var())) + 1e-6
        return _auc(failed, normal), float((failed.mean() - normal.mean()) / spread)


def _criterion(found: tuple[float, float]) -> float:
    auc, margin = found
    return auc + 0.02 * float(np.tanh(margin / 4))


def fit_selection(
    runs: Sequence[np.ndarray],
    failure: Sequence[bool],
    onsets: Sequence[int],
    all_groups: Sequence[Group],
) -> tuple[Selection | None, str]:
    """The selection among `all_groups` (`groups`) for one task's training runs (each its full paired vectors
    (L, W)), or None and why not (too few runs of a kind, or no choice better than every element)."""
    failures, successes = sum(map(bool, failure)), sum(not f for f in failure)
    if failures < MIN_RUNS or successes < MIN_RUNS:
        return None, (
            f"every dimension kept: {failures} failure and {successes} success runs, and choosing needs at least "
            f"{MIN_RUNS} of each"
        )
    fit = _Fit(runs, failure, onsets)
    time = next(g for g in all_groups if g.name == TIME)
    candidates = [g for g in all_groups if g is not time]
    every = sum((fit.distances(g) for g in all_groups), np.zeros((len(fit.run),) * 2))
    everything = fit.score(every, sum(len(g.columns) for g in all_groups))
    alone = {g.name: fit.score(fit.distances(g), len(g.columns)) for g in candidates}
    candidates = [g for g in candidates if alone[g.name][0] >= MIN_ALONE]  # each must separate on its own
    current = np.zeros_like(every)
    elements, best, chosen = 0, -np.inf, []
    picked: list[Group] = []
    while len(picked) < MAX_GROUPS:
        trials = [
            (_criterion(found), g, found)
            for g in candidates
            if g not in picked
            for found in [fit.score(current + fit.distances(g), elements + len(g.columns))]
        ]
        if not trials:
            break
        value, group, found = max(trials, key=lambda trial: trial[0])
        if value <= best + MIN_GAIN:
            break
        best, elements = value, elements + len(group.columns)
        current = current + fit.distances(group)
        picked.append(group)
        chosen.append(Chosen(group.name, alone[group.name][0], found[0]))
    phases = [
        (_criterion(found), weight, found)
        for weight in PHASE_WEIGHTS
        for found in [fit.score(current + fit.distances(time, weight), elements + (weight > 0))]
    ]
    value, phase, found = max(phases, key=lambda trial: trial[0])
    if found[0] < everything[0] + MIN_LIFT:
        return None, (
            f"every dimension kept: no choice separated the {failures} failure and {successes} success training "
            f"runs clearly better (cross-validated AUC {found[0]:.3f} chosen, {everything[0]:.3f} every dimension)"
        )
    kept = sorted({c: 1.0 for g in picked for c in g.columns} | ({time.columns[0]: phase} if phase else {}))
    weights = {c: 1.0 for g in picked for c in g.columns} | {time.columns[0]: phase}
    columns = np.asarray(kept, np.int64)
    return (
        Selection(
            columns,
            np.asarray([weights[c] for c in kept], np.float64),
            tuple(chosen),
            phase,
            found[0],
            everything[0],
            (failures, successes),
        ),
        "",
    )


def choose(
    layout: SignalLayout,
    derivation: Derivation | None,
    runs: Sequence[np.ndarray],
    failure: Sequence[bool],
    onsets: Sequence[int],
    *,
    start: bool,
) -> tuple[Selection | None, str]:
    """`fit_selection` for one task's `layout` and `derivation`, its runs' full paired vectors given."""
    state = [f"{name}/{dim}" for name, dims in layout.state for dim in dims]
    action = [f"{name}/{dim}" for name, dims in layout.action for dim in dims]
    derived = derivation.names(layout.raw_columns()) if derivation is not None else []
    steps = len(derivation.steps) if derivation is not None and EVENTS in derivation.kinds else 0
    return fit_selection(runs, failure, onsets, groups(state, derived, action, steps, start=start))


class _Task(Protocol):
    """What choosing reads of a task's signal memory (`task.TaskSignals`)."""

    layout: SignalLayout
    derivation: Derivation | None
    start_weight: float

    def vectors_of(self, features: np.ndarray, frames: np.ndarray | None = None) -> np.ndarray: ...


def choose_for(
    task: _Task, features: Sequence[tuple[Trajectory, np.ndarray]], onset_start: int = 1
) -> tuple[Selection | None, str]:
    """`choose` for a task's signal memory not yet holding runs (its layout, derivation and normalisation) and its
    labelled runs' raw features, each failure's entries from its onset (`onset_start` where not known)."""
    return choose(
        task.layout,
        task.derivation,
        [task.vectors_of(raw) for _, raw in features],
        [run.is_failure for run, _ in features],
        [(run.onset_frame or onset_start) if run.is_failure else 0 for run, _ in features],
        start=task.start_weight > 0,
    )
