"""The evaluate job's config (`EvaluateConfig`, with its `FoldPlan`) and the steps of the job that read it: what
an evaluation learns from and tests on (the training and test splits, disjoint by construction and checked) and
the memory built from the training split. Its run, `run_evaluation` (`evaluation/run.py`), sits above the
modules that take this config too (`folds.py`, `folds_alone.py`), which the layers' no-circle rule keeps below it."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from robofailring.calibration.policy import DEFAULT_POLICY, ThresholdPolicy
from robofailring.data.grounding import Vocabulary
from robofailring.data.layouts import Dataset
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.data.splits import split_of
from robofailring.detection.config import (
    DEFAULT_SCORING,
    DEFAULT_STRIDE,
    DetectorConfig,
    Scoring,
    check_stride,
)
from robofailring.detection.rules import PAPER
from robofailring.encoders import CachedEncoder
from robofailring.encoders.placement import DEFAULT_PLACEMENT, EncoderPlacement
from robofailring.errors import RoboFailRingError, SettingError, SplitError
from robofailring.evaluation.metrics import PAPER_DELTAS
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import DEFAULT_RECIPE, MemoryRecipe
from robofailring.memory.references import absolute_reference
from robofailring.outputs import check_file_stem

#: `--folds loo`: one fold per episode.
LEAVE_ONE_OUT: Final[str] = "loo"


@dataclass(frozen=True)
class FoldPlan:
    """How `evaluate --folds` cuts every labelled run of its data into folds."""

    count: int | None  # folds (≥ 2); None: one per episode (leave-one-episode-out)

    @classmethod
    def parse(cls, text: str) -> FoldPlan:
        """`loo` or a whole number ≥ 2; SettingError otherwise."""
        cleaned = text.strip().lower()
        if cleaned == LEAVE_ONE_OUT:
            return cls(None)
        if not cleaned.isdecimal() or int(cleaned) < 2:
            raise SettingError(f"--folds takes {LEAVE_ONE_OUT} or a whole number ≥ 2, got {text!r}")
        return cls(int(cleaned))

    def describe(self, folds: int) -> str:
        """In words, with the number of folds it gave."""
        if self.count is None:
            return f"leave-one-episode-out: {folds} folds of one run"
        return f"{folds} folds, failures and successes dealt evenly"

    def to_json(self) -> str | int:
        return LEAVE_ONE_OUT if self.count is None else self.count


@dataclass(frozen=True)
class EvaluateConfig:
    data: DataSelection  # the dataset whose training split's failures form the memory, how it is read
    out: Path  # folder for evaluation.json and evaluation.md (and memory/ when built here)
    # the memory built here (encoder, failure frames, pairing, success step); its encoder also opens `memory`
    recipe: MemoryRecipe = DEFAULT_RECIPE
    memory: Path | None = (
        None  # an existing memory (its failures must not be in the test set); None: built here
    )
    # how runs are scored (K, modality; every rule is judged, at thresholds calibrated here or stored)
    scoring: Scoring = DEFAULT_SCORING
    placement: EncoderPlacement = (
        DEFAULT_PLACEMENT  # where the recipe's encoder runs: device, runtime, cache, Ray
    )
    # every rule calibrated here on the training successes (α, band, fusion); None: the memory's stored thresholds
    threshold_policy: ThresholdPolicy | None = DEFAULT_POLICY
    memory_out: Path | None = None  # where a memory built here is saved (default out/memory)
    # a second dataset to test on (e.g. out-of-distribution; `data.other(root, labels=…)` reads it as `data`)
    test_data: DataSelection | None = None
    train_split: str = "train"
    test_split: str = "test"
    test_fraction: float = 0.5  # for datasets without splits: a deterministic hash split
    deltas: tuple[float, ...] = PAPER_DELTAS
    name: str = "evaluation"  # a file name stem: `<name>.json`, `<name>.md`, `<name>.rrd` in `out`
    stride: int = (
        DEFAULT_STRIDE  # score every stride-th frame of a test trajectory (t_det, T_s in original frames)
    )
    success_memory: bool = True  # build the success memory beside the failure memory (contrast rule)
    deployment_successes: int = 0  # per task: test success runs moved into the success memory
    failures_per_task: int | None = None  # the memory built here holds N training failures per task
    # (`labelled_failures`; 0: success runs only, judged by the novelty rule); None: all of them
    folds: FoldPlan | None = None  # also cross-validate over every labelled run of `data` (evaluation.folds)

    def __post_init__(self) -> None:  # bad settings fail before any frame is encoded
        check_stride(self.stride)
        check_file_stem(self.name)  # `<name>.json` and the rest stay inside `out`
        if self.deployment_successes < 0:
            raise SettingError(f"deployment successes must be ≥ 0, got {self.deployment_successes}")
        if self.failures_per_task is not None and self.failures_per_task < 0:
            raise SettingError(f"failures per task must be ≥ 0, got {self.failures_per_task}")
        for delta in self.deltas:
            PAPER.check_threshold(delta)
        if not 0.0 < self.test_fraction < 1.0:
            raise SettingError(f"test fraction must lie in (0, 1), got {self.test_fraction}")
        if self.folds is not None and (self.memory is not None or self.threshold_policy is None):
            raise SettingError(
                "--folds builds a memory and calibrates thresholds per fold from the data: leave out --memory "
                "and give a target FPR"
            )

    @property
    def detector(self) -> DetectorConfig:
        """The detector every rule is judged by: the memory (when given), no rule or threshold of its own."""
        return DetectorConfig(memory=self.memory, scoring=self.scoring, placement=self.placement)


@dataclass(frozen=True)
class Splits:
    """The training and test trajectories of an evaluation, and the dataset the training ones come from."""

    train: list[Trajectory]
    test: list[Trajectory]
    dataset: Dataset  # `config.data`: the training split's dataset
    skipped: list[Skipped]  # what the loaders of the training and test datasets did not read


def load_labelled(
    data: DataSelection, *, vocabulary: Vocabulary | None = None
) -> tuple[Dataset, list[Trajectory], list[Skipped]]:
    """A dataset of the evaluation as its selection reads it (`vocabulary`: the training data's, which its
    labels are read by), its runs with an outcome, and what was not used (an unlabelled run is never taken
    for a success)."""
    loaded = data.load(vocabulary=vocabulary)
    return loaded, *loaded.judged("evaluate")


def select_splits(config: EvaluateConfig) -> Splits:
    """The training and test trajectories, disjoint by construction and checked."""
    vocabulary = config.data.read_vocabulary()
    dataset, source, skipped = load_labelled(config.data, vocabulary=vocabulary)
    has_splits = any(t.split for t in source)

    def of_split(split: str) -> list[Trajectory]:
        return [
            t
            for t in source
            if split_of(t, has_splits=has_splits, test_fraction=config.test_fraction) == split
        ]

    train = of_split(config.train_split)
    if config.test_data is None:
        test = of_split(config.test_split)
    else:
        _, other, other_skipped = load_labelled(config.test_data, vocabulary=vocabulary)
        skipped += other_skipped
        other_has_splits = any(t.split for t in other)
        test = [t for t in other if not other_has_splits or t.split == config.test_split]
    if not test:
        tested = config.test_data.root if config.test_data is not None else config.data.root
        raise SplitError(f"no test trajectories (split {config.test_split!r}) in {tested}")
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


def evaluation_encoder(config: EvaluateConfig) -> CachedEncoder:
    """The encoder an evaluation builds its memories with: its recipe's, where its placement says (device,
    runtime, cache, Ray cluster)."""
    return config.placement.open(config.recipe.encoder)


def build_training_memory(
    config: EvaluateConfig, splits: Splits | None = None, encoder: CachedEncoder | None = None
) -> tuple[Path, list[Skipped]]:
    """Build the memory from the training split's failures (and successes) and save it to `config.memory_out`;
    its folder and what the build did not use (`BuildStats.skipped_inputs`, kept in its manifest too)."""
    if encoder is None:
        encoder = evaluation_encoder(config)
    if splits is None:
        splits = select_splits(config)
    provenance = Provenance(
        data=config.data.root,
        encoder=config.recipe.encoder,
        layout=splits.dataset.layout,
        views=splits.dataset.views,
        split=config.train_split,
        skipped_inputs=splits.dataset.skipped,
    )
    memory, stats = build_memories(
        labelled_failures(splits.train, config.failures_per_task),
        encoder,
        provenance=provenance,
        recipe=config.recipe,
        successes=config.success_memory,
        vocabulary=config.data.read_vocabulary(),
    )
    memory_dir = config.memory_out or Path(config.out) / "memory"
    memory.save(memory_dir)
    return memory_dir, stats.skipped_inputs


def labelled_failures(trajectories: Sequence[Trajectory], per_task: int | None) -> list[Trajectory]:
    """The success runs and `per_task` failure runs of each task (None: all of them), the failures
    in a fixed pseudo-random order (a hash of their key), so the few that are labelled are of mixed types."""
    if per_task is None:
        return list(trajectories)
    kept: dict[str, int] = {}
    chosen = []
    for trajectory in sorted(
        trajectories, key=lambda t: hashlib.blake2b(t.key.encode(), digest_size=8).digest()
    ):
        if trajectory.is_failure:
            if kept.get(trajectory.task, 0) >= per_task:
                continue
            kept[trajectory.task] = kept.get(trajectory.task, 0) + 1
        chosen.append(trajectory)
    return chosen
