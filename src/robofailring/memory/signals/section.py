"""The manifest's `signals` section as a typed value: `SignalSection` (how the signals were chosen, the derived
features, the start weight) and per task a `TaskSection` (its key in `signals.npz`, its layout, its entries and
what `--signals auto` chose). Read once with the manifest (every check of the section here), written back as the
same JSON: a key it does not know is kept verbatim, and a key a memory from an older version lacks (its
`features`, `start_weight`) is read as that version meant it and not written.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from robofailring.bounded import Shape, read_npz
from robofailring.errors import MemoryFormatError
from robofailring.memory.format import is_whole
from robofailring.memory.signals.derived import NO_FEATURES, Derivation, SignalFeatures
from robofailring.memory.signals.layout import AUTO, SignalLayout, check_choice
from robofailring.memory.signals.task import START_WEIGHT, check_start_weight, vector_width

SIGNALS_FILE: Final[str] = "signals.npz"
KINDS: Final[tuple[str, str]] = ("failure", "success")  # a task's two indexes
PARTS: Final[tuple[str, ...]] = ("episodes", "symbols", "frames")  # each index's rows (`rows.Rows`)
STEPS: Final[tuple[str, str]] = ("steps", "step_tolerance")  # a derivation's arrays, per task key
_SECTION_KEYS: Final[tuple[str, ...]] = ("file", "choice", "features", "start_weight", "tasks")
_TASK_KEYS: Final[tuple[str, ...]] = (
    "key",
    "layout",
    "selection",
    "selection_skipped",
    "failure_entries",
    "success_entries",
)


@dataclass(frozen=True)
class TaskSection:
    """One task's entry of the section: its key in `signals.npz`, its layout and its entries per index."""

    key: str  # the prefix of its arrays in the file (`t0_mean`, …)
    layout: SignalLayout
    entries: Mapping[str, int]  # per index (`failure`, `success`): its entries
    selection: Mapping[str, Any] | None = (
        None  # what `--signals auto` kept and why (`select.Selection.describe`)
    )
    selection_skipped: str | None = None  # why nothing was chosen, where choosing was asked for
    extra: Mapping[str, Any] = field(default_factory=dict)  # keys this version does not know, kept verbatim

    @property
    def selected(self) -> int | None:
        """How many elements of its vectors the selection keeps (None: every one)."""
        return None if self.selection is None else int(self.selection["elements"])

    @classmethod
    def parse(cls, task: str, described: Any, where: str) -> TaskSection:
        if not isinstance(described, dict):
            raise MemoryFormatError(
                f"{where}: the signal memory's task {task!r} is {described!r}, not an object"
            )
        key = described.get("key")
        if not isinstance(key, str) or not key:
            raise MemoryFormatError(f"{where}: the signal memory's task {task!r} has no key ({key!r})")
        if "layout" not in described:
            raise MemoryFormatError(f"{where}: the signal memory lacks 'layout' (a damaged file?)")
        entries = {}
        for kind in KINDS:
            count = described.get(f"{kind}_entries")
            if not is_whole(count) or count < 0:
                raise MemoryFormatError(f"{where}: the manifest's {kind}_entries {count!r} is not a count")
            entries[kind] = count
        selection = described.get("selection")
        if selection is not None:  # `--signals auto` kept these elements of the vectors (select.py)
            kept = selection.get("elements") if isinstance(selection, dict) else None
            if not is_whole(kept) or kept <= 0:
                raise MemoryFormatError(f"{where}: task key {key!r} keeps {kept!r} signal elements")
        skipped = described.get("selection_skipped")
        return cls(
            key,
            SignalLayout.parse(described["layout"], where),
            entries,
            selection,
            None if skipped is None else str(skipped),
            {k: v for k, v in described.items() if k not in _TASK_KEYS},
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "layout": self.layout.to_dict(),
            **({"selection": self.selection} if self.selection is not None else {}),
            **({"selection_skipped": self.selection_skipped} if self.selection_skipped is not None else {}),
            **{f"{kind}_entries": count for kind, count in self.entries.items()},
            **self.extra,
        }


@dataclass(frozen=True)
class SignalSection:
    """The manifest's `signals` section: the choice of signals, the derived features and start weight new tasks
    are built with, and each task's entry."""

    tasks: Mapping[str, TaskSection]
    choice: str = AUTO  # `--signals` as given
    features: SignalFeatures = NO_FEATURES  # a memory from before derived features: none
    start_weight: float = START_WEIGHT  # a memory from before it was a setting: ½
    file: str = SIGNALS_FILE
    extra: Mapping[str, Any] = field(default_factory=dict)  # keys this version does not know, kept verbatim
    absent: frozenset[str] = field(default=frozenset(), repr=False)  # known keys the file did not have

    @classmethod
    def parse(cls, section: Any, where: str | Path) -> SignalSection:
        """The section read from the manifest at `where`; MemoryFormatError naming what is wrong."""
        where = str(where)
        if not isinstance(section, dict):
            raise MemoryFormatError(f"{where}: the signal memory's section is {section!r}, not an object")
        tasks = section.get("tasks")
        if not isinstance(tasks, dict):
            raise MemoryFormatError(f"{where}: the signal memory lacks 'tasks' (a damaged file?)")
        try:
            choice = check_choice(section.get("choice", AUTO))
            features = section.get("features", str(NO_FEATURES))
            if not isinstance(features, str):
                raise ValueError(f"features {features!r} are not a string")
            parsed = SignalFeatures.parse(features)
            start_weight = check_start_weight(section.get("start_weight", START_WEIGHT))
        except ValueError as error:
            raise MemoryFormatError(f"{where}: the signal memory's section: {error}") from error
        return cls(
            {str(task): TaskSection.parse(str(task), described, where) for task, described in tasks.items()},
            choice,
            parsed,
            start_weight,
            str(section.get("file", SIGNALS_FILE)),
            {k: v for k, v in section.items() if k not in _SECTION_KEYS},
            frozenset(k for k in _SECTION_KEYS if k not in section),
        )

    def to_dict(self) -> dict[str, Any]:
        """The section as JSON, as it was read (or as `SignalMemory.manifest` made it)."""
        values = {
            "file": self.file,
            "choice": self.choice,
            "features": str(self.features),
            "start_weight": self.start_weight,
            "tasks": {task: described.to_dict() for task, described in self.tasks.items()},
        }
        return {k: v for k, v in values.items() if k not in self.absent} | dict(self.extra)

    def expected_shapes(self, path: Path) -> dict[str, Shape]:
        """Each array of `signals.npz` at `path` and its shape as the section says it (its entry counts and its
        layouts' widths), reading first only the small step-like-column arrays the vectors' width depends on."""
        where = str(path)
        derived = {task.key for task in self.tasks.values() if task.layout.derived}
        steps = read_npz(
            path,
            error=MemoryFormatError,
            names=[f"{key}_{part}" for key in derived for part in STEPS],
            shapes={f"{task.key}_{part}": (None,) for task in self.tasks.values() for part in STEPS},
        )
        shapes: dict[str, Shape] = {}
        for task in self.tasks.values():
            key, layout = task.key, task.layout
            state, action = layout.widths
            if layout.derived:
                state += Derivation.read(layout.derived, state + action, steps, key, where).width
            shapes[f"{key}_mean"] = shapes[f"{key}_scale"] = (state + action + 1,)  # [state ‖ action ‖ t]
            width = vector_width(state, action)
            kept = task.selected
            if kept is not None:
                if kept > width:
                    raise MemoryFormatError(
                        f"{where}: task key {key!r} keeps {kept!r} signal elements of {width}"
                    )
                width = kept
                shapes[f"{key}_selected"] = shapes[f"{key}_selected_weights"] = (kept,)
            for kind, entries in task.entries.items():
                shapes[f"{key}_{kind}"] = (entries, width)
                for part in PARTS:
                    shapes[f"{key}_{kind}_{part}"] = (entries,)
        return shapes
