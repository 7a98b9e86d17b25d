"""What an evaluation learns from and tests on: the training and test splits of its data (a test dataset read
by its own `DataSelection`), disjoint by construction, and the check that no test run is in the memory."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from robofailring.data.grounding import Vocabulary
from robofailring.data.layouts import Dataset
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.data.splits import split_of
from robofailring.errors import RoboFailRingError, SplitError
from robofailring.memory.failure import FailureMemory
from robofailring.memory.references import absolute_reference


@dataclass(frozen=True)
class Splits:
    """The training and test trajectories of an evaluation, and the dataset the training ones come from."""

    train: list[Trajectory]
    test: list[Trajectory]
    dataset: Dataset  # the training split's dataset
    skipped: list[Skipped]  # what the loaders of the training and test datasets did not read


def load_labelled(
    data: DataSelection, *, vocabulary: Vocabulary | None = None
) -> tuple[Dataset, list[Trajectory], list[Skipped]]:
    """A dataset of the evaluation as its selection reads it (`vocabulary`: the training data's, which its
    labels are read by), its runs with an outcome, and what was not used (an unlabelled run is never taken
    for a success)."""
    loaded = data.load(vocabulary=vocabulary)
    return loaded, *loaded.judged("evaluate")


def split_data(
    data: DataSelection,
    test_data: DataSelection | None,
    *,
    train_split: str,
    test_split: str,
    test_fraction: float,
) -> Splits:
    """`data`'s `train_split` runs and the `test_split` runs of `test_data` (None: of `data`; a dataset without
    splits: a deterministic hash split at `test_fraction`), disjoint by construction; SplitError without a
    test run."""
    vocabulary = data.read_vocabulary()
    dataset, source, skipped = load_labelled(data, vocabulary=vocabulary)
    has_splits = any(t.split for t in source)

    def of_split(split: str) -> list[Trajectory]:
        return [t for t in source if split_of(t, has_splits=has_splits, test_fraction=test_fraction) == split]

    train = of_split(train_split)
    if test_data is None:
        test = of_split(test_split)
    else:
        _, other, other_skipped = load_labelled(test_data, vocabulary=vocabulary)
        skipped += other_skipped
        other_has_splits = any(t.split for t in other)
        test = [t for t in other if not other_has_splits or t.split == test_split]
    if not test:
        tested = test_data.root if test_data is not None else data.root
        raise SplitError(f"no test trajectories (split {test_split!r}) in {tested}")
    return Splits(train=train, test=test, dataset=dataset, skipped=skipped)


def check_disjoint(memory: FailureMemory, test: Sequence[Trajectory]) -> None:
    """No trajectory may be both in the memory and in the test set (compared by its image files)."""
    in_memory = {absolute_reference(ref) for entry in memory.entries for ref in (entry.start, entry.end)}
    for trajectory in test:
        for frames in trajectory.views.values():
            if (
                frames
                and {absolute_reference(frames[0].reference), absolute_reference(frames[-1].reference)}
                & in_memory
            ):
                raise RoboFailRingError(
                    f"test trajectory {trajectory.key} ({trajectory.source}) is also in the memory; "
                    "evaluate on a split the memory was not built from"
                )
