"""The signal memory: the robot's own signals (joint state, gripper, end-effector pose, commanded actions)
as a second modality beside the cameras, retrieved as the paper retrieves frames (docs/signals.md).

Per task, each frame t of a run becomes one vector from its raw features f_t = [state ‖ action ‖ t]
(the layout's state and action signals and the frame number; with derived features,
`robofailring.memory.signals.derived`, the state is followed by them), z-scored by the task's own success
runs (all its runs where it has none) to z_t, then paired as the memory's frames are paired:
`[w·zs_0 ‖ zs_t − zs_0 ‖ za_t ‖ za_{t−2} ‖ za_{t−4} ‖ z_time_t]` (the start state weighted by w, the
change since then, a short window of commanded actions, the moment; w is the memory's `start_weight`: 0 by
default, since where a run starts varies with where things were placed and says nothing of how it goes; ½,
as the `change` pairing weighs the first frame, in memories from before it was a setting). Failure runs give one entry per frame from
their onset on (from frame 1 when unknown), success runs one per frame, each set in its own exact
Faiss index per task. A query's similarity to an entry is exp(−d²/n) (d its Euclidean distance, n the
vector's length), in (0, 1]; S⁻ is the nearest failure's, S⁺ the nearest success's, scored by the
rules and fused with the camera views as one more view named `signals`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Final

import numpy as np

from robofailring.bounded import read_npz
from robofailring.data.model import Skipped, Trajectory
from robofailring.errors import DataError, MemoryFormatError
from robofailring.memory.signals.derived import NO_FEATURES, Derivation, SignalFeatures
from robofailring.memory.signals.layout import (
    AUTO,
    SignalLayout,
    choose_layout,
    read_features,
)
from robofailring.memory.signals.rows import Rows, rows_of
from robofailring.memory.signals.section import KINDS, PARTS, SIGNALS_FILE, SignalSection, TaskSection
from robofailring.memory.signals.select import Selection, choose_for
from robofailring.memory.signals.task import START_WEIGHT, TaskSignals

# the start state's weight in a new memory (docs/signals.md, "Measured"; ½ in one from before the setting)
DEFAULT_START_WEIGHT: Final[float] = 0.0
MIN_SCALE: Final[float] = 1e-3  # a feature's spread floor (a value constant over the successes)


def build_task(
    trajectories: Sequence[Trajectory],
    layout: SignalLayout,
    onset_start: int = 1,
    *,
    start_weight: float = DEFAULT_START_WEIGHT,
    select: bool = False,
) -> tuple[TaskSignals | None, list[Skipped]]:
    """One task's signal memory from its labelled runs; a run whose signals cannot be read is skipped.
    `select`: its vectors keep the elements that separate its failure runs from its success runs
    (`robofailring.memory.signals.select`)."""
    features: list[tuple[Trajectory, np.ndarray]] = []
    skipped: list[Skipped] = []
    for trajectory in trajectories:
        if trajectory.outcome is None:
            continue
        try:
            features.append((trajectory, read_features(trajectory, layout)))
        except DataError as error:
            skipped.append(_not_used(trajectory, str(error)))
    normal = [f for t, f in features if not t.is_failure] or [f for _, f in features]
    if not normal:
        return None, skipped
    derivation = Derivation.fit(layout.derived, sum(layout.widths), normal) if layout.derived else None
    empty = TaskSignals(layout, np.zeros(0), np.ones(0), {}, {}, derivation)
    stacked = np.concatenate([empty.derived(f) for f in normal])
    mean, scale = stacked.mean(axis=0), np.maximum(stacked.std(axis=0), MIN_SCALE)
    task = TaskSignals(layout, mean, scale, {}, {}, derivation, start_weight)
    if select:
        task = TaskSignals(
            layout, mean, scale, {}, {}, derivation, start_weight, *choose_for(task, features, onset_start)
        )
    grown, unused = _with_runs(task, features, onset_start)
    return grown, [*skipped, *unused]


def _not_used(run: Trajectory, reason: str) -> Skipped:
    """A run left out of the signal memory, and why (its frames are still used)."""
    return Skipped(run.source or Path(run.key), f"signals not used: {reason}")


def _with_runs(
    task: TaskSignals, features: Sequence[tuple[Trajectory, np.ndarray]], onset_start: int = 1
) -> tuple[TaskSignals, list[Skipped]]:
    """`task` with an entry per frame of each run added (a failure's from its onset on), its normalisation
    kept, and the runs whose vectors it cannot keep."""
    skipped: list[Skipped] = []
    vectors: dict[str, list[np.ndarray]] = {kind: [v] for kind, v in task.vectors.items()}
    rows: dict[str, list[tuple[str, str, int]]] = {
        kind: list(zip(r.episodes.tolist(), r.symbols.tolist(), r.frames.tolist(), strict=True))
        for kind, r in task.rows.items()
    }
    for trajectory, raw in features:
        kind = "failure" if trajectory.is_failure else "success"
        start = (trajectory.onset_frame or onset_start) if kind == "failure" else 0
        try:
            paired = task.vectors_of(raw)[start:]
        except DataError as error:
            skipped.append(_not_used(trajectory, f"{trajectory.key}: {error}"))
            continue
        vectors.setdefault(kind, []).append(paired)
        found = rows.setdefault(kind, [])
        found += [(trajectory.episode, trajectory.symbol or "", start + i) for i in range(len(paired))]
    width = task.width
    grown = TaskSignals(
        task.layout,
        task.mean,
        task.scale,
        {
            kind: np.concatenate(vectors[kind]) if vectors.get(kind) else np.zeros((0, width), np.float32)
            for kind in KINDS
        },
        {kind: rows_of(rows.get(kind, [])) for kind in KINDS},
        task.derivation,
        task.start_weight,
        task.selection,
        task.chose,
    )
    return grown, skipped


class SignalMemory:
    """Every task's signal memory (`TaskSignals`), the choice of signals it was built with, saved as one
    `.npz` beside the memory's index (no pickles) and described in its manifest's `signals` section."""

    def __init__(
        self,
        by_task: Mapping[str, TaskSignals],
        *,
        choice: str = AUTO,
        features: SignalFeatures = NO_FEATURES,
        start_weight: float = START_WEIGHT,
    ) -> None:
        self.by_task = dict(by_task)
        self.choice = choice
        self.features = features  # the derived features (`--signal-features`) a new task is built with
        self.start_weight = float(start_weight)  # the start state's weight w in every task's vectors

    @classmethod
    def build(
        cls,
        trajectories: Sequence[Trajectory],
        *,
        choice: str = AUTO,
        features: SignalFeatures = NO_FEATURES,
        start_weight: float = DEFAULT_START_WEIGHT,
    ) -> tuple[SignalMemory | None, list[Skipped]]:
        """The signal memory of the labelled `trajectories` (None: no task has signals to use), with the
        derived `features` (`none`, or `change` and/or `events`: `robofailring.memory.signals.derived`) and the
        start state weighted by `start_weight` (module docstring)."""
        by_task: dict[str, TaskSignals] = {}
        skipped: list[Skipped] = []
        tasks = sorted({t.task for t in trajectories})
        for task in tasks:
            runs = [t for t in trajectories if t.task == task]
            layout, unused = choose_layout(runs, choice, features)
            skipped += unused
            if layout is None:
                continue
            built, missed = build_task(runs, layout, start_weight=start_weight, select=choice == AUTO)
            skipped += missed
            if built is not None:
                by_task[task] = built
        built_memory = cls(by_task, choice=choice, features=features, start_weight=start_weight)
        return (built_memory if by_task else None), skipped

    def extended(self, trajectories: Sequence[Trajectory]) -> tuple[SignalMemory, list[Skipped]]:
        """This memory with the labelled `trajectories` added: a task it has keeps its layout and
        normalisation (a run without its signals is skipped), a new task is built as `build` builds one."""
        by_task = dict(self.by_task)
        skipped: list[Skipped] = []
        for task in sorted({t.task for t in trajectories}):
            runs = [t for t in trajectories if t.task == task and t.outcome is not None]
            held = by_task.get(task)
            if held is None:
                layout, unused = choose_layout(runs, self.choice, self.features)
                skipped += unused
                built, missed = (
                    build_task(runs, layout, start_weight=self.start_weight, select=self.choice == AUTO)
                    if layout is not None
                    else (None, [])
                )
                skipped += missed
                if built is not None:
                    by_task[task] = built
                continue
            features = []
            for run in runs:
                try:
                    features.append((run, read_features(run, held.layout)))
                except DataError as error:
                    skipped.append(_not_used(run, str(error)))
            by_task[task], unused = _with_runs(held, features)
            skipped += unused
        return (
            SignalMemory(by_task, choice=self.choice, features=self.features, start_weight=self.start_weight),
            skipped,
        )

    def task(self, task: str) -> TaskSignals | None:
        return self.by_task.get(task)

    def __len__(self) -> int:
        return sum(len(v) for task in self.by_task.values() for v in task.vectors.values())

    def manifest(self) -> SignalSection:
        """The manifest's `signals` section: the choice, and per task its key in the file, layout and sizes."""
        tasks = {
            task: TaskSection(
                f"t{number}",
                signals.layout,
                {kind: len(v) for kind, v in signals.vectors.items()},
                signals.selection.describe() if signals.selection is not None else None,
                signals.chose or None,
            )
            for number, (task, signals) in enumerate(sorted(self.by_task.items()))
        }
        return SignalSection(tasks, self.choice, self.features, self.start_weight)

    def write(self, directory: Path) -> None:
        """Write `signals.npz` into `directory` (the memory's folder being written), keyed as `manifest` says."""
        arrays: dict[str, np.ndarray] = {}
        for task, described in self.manifest().tasks.items():
            key, signals = described.key, self.by_task[task]
            arrays[f"{key}_mean"], arrays[f"{key}_scale"] = signals.mean, signals.scale
            if signals.derivation is not None:
                arrays |= signals.derivation.arrays(key)
            if signals.selection is not None:
                arrays |= signals.selection.arrays(key)
            for kind in KINDS:
                rows = signals.rows[kind]
                arrays[f"{key}_{kind}"] = signals.vectors[kind]
                arrays |= {f"{key}_{kind}_{part}": getattr(rows, part) for part in PARTS}
        with (Path(directory) / SIGNALS_FILE).open("wb") as handle:
            np.savez(handle, **arrays)  # type: ignore[arg-type]  # numpy's stub types **kwds as allow_pickle

    @classmethod
    def read(cls, directory: Path, section: SignalSection) -> SignalMemory:
        """What `write` wrote, checked: a missing array or a size other than the manifest's names the file."""
        path = Path(directory) / SIGNALS_FILE
        where = f"{path}"
        try:
            # each array's declared shape checked against the manifest before it is decompressed
            arrays = read_npz(path, error=MemoryFormatError, shapes=section.expected_shapes(path))
            by_task = {}
            for task, described in section.tasks.items():
                key, layout = described.key, described.layout
                vectors = {kind: arrays[f"{key}_{kind}"] for kind in KINDS}
                rows = {kind: Rows(*(arrays[f"{key}_{kind}_{part}"] for part in PARTS)) for kind in vectors}
                for kind, found in vectors.items():
                    if len(found) != described.entries[kind] or len(rows[kind].episodes) != len(found):
                        raise MemoryFormatError(
                            f"{where}: task {task!r} has {len(found)} {kind} vectors, the manifest says "
                            f"{described.entries[kind]}"
                        )
                derivation = (
                    Derivation.read(layout.derived, sum(layout.widths), arrays, key, where)
                    if layout.derived
                    else None
                )
                full = TaskSignals(layout, np.zeros(0), np.ones(0), {}, {}, derivation).width
                selection = (
                    Selection.read(described.selection, arrays, key, full, where)
                    if described.selection is not None
                    else None
                )
                by_task[task] = TaskSignals(
                    layout,
                    arrays[f"{key}_mean"],
                    arrays[f"{key}_scale"],
                    vectors,
                    rows,
                    derivation,
                    section.start_weight,
                    selection,
                    described.selection_skipped or "",
                )
        except (KeyError, TypeError, AttributeError) as error:
            raise MemoryFormatError(f"{where}: the signal memory lacks {error} (a damaged file?)") from error
        return cls(
            by_task, choice=section.choice, features=section.features, start_weight=section.start_weight
        )
