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
from typing import Any, Final

import numpy as np

from robofailring.bounded import Shape, read_npz
from robofailring.data.model import Skipped, Trajectory
from robofailring.errors import DataError, MemoryFormatError
from robofailring.memory.signals.derived import NONE as NO_FEATURES
from robofailring.memory.signals.derived import Derivation
from robofailring.memory.signals.layout import (
    AUTO,
    SignalLayout,
    choose_layout,
    read_features,
)
from robofailring.memory.signals.rows import Rows, rows_of
from robofailring.memory.signals.select import Selection, choose_for
from robofailring.memory.signals.task import START_WEIGHT, TaskSignals, vector_width

# the start state's weight in a new memory (docs/signals.md, "Measured"; ½ in one from before the setting)
DEFAULT_START_WEIGHT: Final[float] = 0.0
# the largest start weight: the start state, a few σ once normalised, then outweighs every other element a
# hundredfold; a larger one only overflows the float32 vectors (1e308 would make them infinite)
MAX_START_WEIGHT: Final[float] = 100.0
MIN_SCALE: Final[float] = 1e-3  # a feature's spread floor (a value constant over the successes)
SIGNALS_FILE: Final[str] = "signals.npz"
STEPS: Final[tuple[str, str]] = ("steps", "step_tolerance")  # a derivation's arrays, per task key


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
            for kind in ("failure", "success")
        },
        {kind: rows_of(rows.get(kind, [])) for kind in ("failure", "success")},
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
        features: str = NO_FEATURES,
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
        features: str = NO_FEATURES,
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

    def manifest(self) -> dict[str, Any]:
        """The manifest's `signals` section: the choice, and per task its key in the file, layout and sizes."""
        tasks = {
            task: {
                "key": f"t{number}",
                "layout": signals.layout.to_dict(),
                **({"selection": signals.selection.describe()} if signals.selection is not None else {}),
                **({"selection_skipped": signals.chose} if signals.chose else {}),
                **{f"{kind}_entries": len(v) for kind, v in signals.vectors.items()},
            }
            for number, (task, signals) in enumerate(sorted(self.by_task.items()))
        }
        return {
            "file": SIGNALS_FILE,
            "choice": self.choice,
            "features": self.features,
            "start_weight": self.start_weight,
            "tasks": tasks,
        }

    def write(self, directory: Path) -> None:
        """Write `signals.npz` into `directory` (the memory's folder being written), keyed as `manifest` says."""
        arrays: dict[str, np.ndarray] = {}
        for task, described in self.manifest()["tasks"].items():
            key, signals = described["key"], self.by_task[task]
            arrays[f"{key}_mean"], arrays[f"{key}_scale"] = signals.mean, signals.scale
            if signals.derivation is not None:
                arrays |= signals.derivation.arrays(key)
            if signals.selection is not None:
                arrays |= signals.selection.arrays(key)
            for kind in ("failure", "success"):
                rows = signals.rows[kind]
                arrays[f"{key}_{kind}"] = signals.vectors[kind]
                arrays[f"{key}_{kind}_episodes"] = rows.episodes
                arrays[f"{key}_{kind}_symbols"] = rows.symbols
                arrays[f"{key}_{kind}_frames"] = rows.frames
        with (Path(directory) / SIGNALS_FILE).open("wb") as handle:
            np.savez(handle, **arrays)  # type: ignore[arg-type]  # numpy's stub types **kwds as allow_pickle

    @classmethod
    def read(cls, directory: Path, section: Mapping[str, Any]) -> SignalMemory:
        """What `write` wrote, checked: a missing array or a size other than the manifest's names the file."""
        path = Path(directory) / SIGNALS_FILE
        where = f"{path}"
        start_weight = _start_weight(section, where)
        try:
            # each array's declared shape checked against the manifest before it is decompressed
            arrays = read_npz(path, error=MemoryFormatError, shapes=_expected_shapes(path, section, where))
            by_task = {}
            for task, described in section["tasks"].items():
                key = described["key"]
                vectors = {kind: arrays[f"{key}_{kind}"] for kind in ("failure", "success")}
                rows = {
                    kind: Rows(
                        *(arrays[f"{key}_{kind}_{part}"] for part in ("episodes", "symbols", "frames"))
                    )
                    for kind in vectors
                }
                for kind, found in vectors.items():
                    if len(found) != described[f"{kind}_entries"] or len(rows[kind].episodes) != len(found):
                        raise MemoryFormatError(
                            f"{where}: task {task!r} has {len(found)} {kind} vectors, the manifest says "
                            f"{described[f'{kind}_entries']}"
                        )
                layout = SignalLayout.parse(described["layout"], where)
                derivation = (
                    Derivation.read(layout.derived, sum(layout.widths), arrays, key, where)
                    if layout.derived
                    else None
                )
                full = TaskSignals(layout, np.zeros(0), np.ones(0), {}, {}, derivation).width
                selection = Selection.stored(described, arrays, key, full, where)
                by_task[str(task)] = TaskSignals(
                    layout,
                    arrays[f"{key}_mean"],
                    arrays[f"{key}_scale"],
                    vectors,
                    rows,
                    derivation,
                    start_weight,
                    selection,
                    str(described.get("selection_skipped", "")),
                )
        except (KeyError, TypeError, AttributeError) as error:
            raise MemoryFormatError(f"{where}: the signal memory lacks {error} (a damaged file?)") from error
        return cls(
            by_task,
            choice=str(section.get("choice", AUTO)),
            features=str(section.get("features", NO_FEATURES)),  # a memory from before derived features: none
            start_weight=start_weight,
        )


def check_start_weight(weight: object) -> float:
    """A start weight (`--signal-start-weight`) as a float; ValueError unless a number from 0 to `MAX_START_WEIGHT`."""
    if (
        isinstance(weight, bool)
        or not isinstance(weight, (int, float))
        or not 0 <= weight <= MAX_START_WEIGHT  # NaN too
    ):
        raise ValueError(
            f"a signal start weight (--signal-start-weight) must be a number from 0 to {MAX_START_WEIGHT:g} "
            f"(0 leaves the start state out, 0.5 weighs it as memories from before the setting do), got {weight!r}"
        )
    return float(weight)


def _expected_shapes(path: Path, section: Mapping[str, Any], where: str) -> dict[str, Shape]:
    """Each array's shape as the manifest's `section` says it (its entry counts and its layout's widths),
    reading first only the small step-like-column arrays the vectors' width depends on."""
    derived: dict[str, tuple[SignalLayout, Derivation | None]] = {}
    for described in section["tasks"].values():
        layout = SignalLayout.parse(described["layout"], where)
        derived[described["key"]] = (layout, None)
    steps = read_npz(
        path,
        error=MemoryFormatError,
        names=[f"{key}_{part}" for key, (layout, _) in derived.items() if layout.derived for part in STEPS],
        shapes={f"{key}_{part}": (None,) for key in derived for part in STEPS},
    )
    shapes: dict[str, Shape] = {}
    for described in section["tasks"].values():
        key = described["key"]
        layout = derived[key][0]
        state, action = layout.widths
        if layout.derived:
            state += Derivation.read(layout.derived, state + action, steps, key, where).width
        shapes[f"{key}_mean"] = shapes[f"{key}_scale"] = (state + action + 1,)  # [state ‖ action ‖ t]
        width = vector_width(state, action)
        selection = described.get("selection")
        if selection is not None:  # `--signals auto` kept these elements of the vectors (select.py)
            kept = selection.get("elements") if isinstance(selection, dict) else None
            if isinstance(kept, bool) or not isinstance(kept, int) or not 0 < kept <= width:
                raise MemoryFormatError(
                    f"{where}: task key {key!r} keeps {kept!r} signal elements of {width}"
                )
            width = kept
            shapes[f"{key}_selected"] = shapes[f"{key}_selected_weights"] = (kept,)
        for kind in ("failure", "success"):
            entries = described[f"{kind}_entries"]
            if isinstance(entries, bool) or not isinstance(entries, int) or entries < 0:
                raise MemoryFormatError(f"{where}: the manifest's {kind}_entries {entries!r} is not a count")
            shapes[f"{key}_{kind}"] = (entries, width)
            for part in ("episodes", "symbols", "frames"):
                shapes[f"{key}_{kind}_{part}"] = (entries,)
    return shapes


def _start_weight(section: Mapping[str, Any], where: str) -> float:
    """The stored start-state weight (a memory from before it was a setting: ½); MemoryFormatError if not one
    `check_start_weight` takes."""
    try:
        return check_start_weight(section.get("start_weight", START_WEIGHT))
    except ValueError as error:
        raise MemoryFormatError(f"{where}: the signal memory's start_weight: {error}") from error
