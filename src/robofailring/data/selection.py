"""`DataSelection`: what a job reads of a dataset (its root, labels, task, views and vocabulary) as one value.

Every job that reads data holds one and reads through it, so `--labels`, `--task`, `--views` and
`--vocabulary` mean the same in every verb; its settings are checked where it is made, before any
frame is read. The robot's signals a memory uses are its recipe's (`robofailring.memory.recipe`): a
memory keeps them, as it keeps its pairing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from robofailring.data.grounding import Vocabulary
from robofailring.data.layouts import Dataset, load_dataset, load_trajectory
from robofailring.data.model import Trajectory
from robofailring.data.views import ViewSelection
from robofailring.data.vocabulary import read_vocabulary


@dataclass(frozen=True)
class DataSelection:
    """A dataset root of any layout (or one episode folder, or an HDF5 file) and how its runs are read."""

    root: Path  # the dataset root, one episode folder or an HDF5 file
    labels: Path | None = None  # outcome, symbol (and task) per episode, for data whose names do not say
    task: str | None = None  # task of episodes whose names do not say it (an episode folder, video episodes)
    views: str | None = None  # `--views`: `a,b` picks views, `src=name` renames (default: every view)
    vocabulary: Path | None = None  # the data's own failure symbols (JSON/YAML) beyond Table 5

    def __post_init__(self) -> None:  # a bad setting fails before anything is read
        object.__setattr__(self, "root", Path(self.root))
        if self.labels is not None:
            object.__setattr__(self, "labels", Path(self.labels))
        if self.vocabulary is not None:
            object.__setattr__(self, "vocabulary", Path(self.vocabulary))
        if self.views is not None:
            ViewSelection.parse(self.views)

    def other(self, root: Path, *, labels: Path | None = None) -> DataSelection:
        """Another dataset read the same way (task, views, vocabulary), with its own `labels` (None: these):
        two LeRobot datasets both number their episodes from 0, so each needs its own labels file."""
        return replace(self, root=Path(root), labels=labels if labels is not None else self.labels)

    def read_vocabulary(self) -> Vocabulary | None:
        """The vocabulary file's symbols (None: Table 5 alone)."""
        return read_vocabulary(self.vocabulary) if self.vocabulary is not None else None

    def load(self, *, vocabulary: Vocabulary | None = None, keys: Sequence[str] | None = None) -> Dataset:
        """The dataset as this selection reads it (`keys`: only the trajectories named); `vocabulary`: the one
        its labels are read by when a memory keeps its own (default: this selection's file)."""
        return load_dataset(
            self.root,
            task=self.task,
            labels=self.labels,
            views=self.views,
            vocabulary=vocabulary if vocabulary is not None else self.read_vocabulary(),
            keys=keys,
        )

    def load_trajectory(self, *, key: str | None = None, vocabulary: Vocabulary | None = None) -> Trajectory:
        """One trajectory: the episode folder `root`, or the one named `key` in the dataset root `root`."""
        return load_trajectory(
            self.root,
            task=self.task,
            key=key,
            labels=self.labels,
            views=self.views,
            vocabulary=vocabulary if vocabulary is not None else self.read_vocabulary(),
        )
