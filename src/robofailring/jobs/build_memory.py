"""The build-memory job: a dataset's failure (and success) runs encoded into a memory folder."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from robofailring.atomic import output_lock
from robofailring.data.labels import label_key, read_labels
from robofailring.data.layouts import Dataset, load_dataset
from robofailring.data.model import Outcome, Trajectory
from robofailring.data.vocabulary import read_vocabulary
from robofailring.detection.rules import RULES
from robofailring.encoders import open_encoder
from robofailring.errors import DataError, MemoryFormatError, SettingError
from robofailring.memory.builder import Provenance, add_to, build_memories
from robofailring.memory.encoding import BuildStats, is_failure
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import MemoryRecipe
from robofailring.outputs import check_memory_target, is_memory_dir


@dataclass(frozen=True)
class BuildMemoryConfig:
    data: Path  # dataset root of any supported layout
    encoder: str  # encoder spec, e.g. `pixels` or `open_clip:ViT-B-32:openai`
    out: Path  # memory directory to write (atomically)
    split: str | None = None  # only trajectories of this split (project layout)
    cache_dir: Path | None = None  # embedding cache (default ~/.cache/robofailring)
    device: str | None = None  # torch device for CLIP (default: cuda when available)
    runtime: str | None = (
        None  # torch, onnx, onnx-int8 or openvino-int8 (default: the spec's own, else torch)
    )
    labels: Path | None = None  # outcome and symbol per episode (needed for LeRobot datasets)
    successes: bool = True  # also build the success memory (contrast rule); False: the paper's memory alone
    success_step: float | None = None  # keep a success frame only this far (cosine) from the last kept one
    task: str | None = None  # task of episodes whose names do not say it (one episode folder, video episodes)
    views: str | None = None  # `--views`: `a,b` picks views, `src=name` renames (default: all)
    vocabulary: Path | None = (
        None  # the dataset's own failure symbols (JSON/YAML), kept in the memory's folder
    )
    add_to: bool = False  # grow the memory at `out` with the dataset's runs instead of replacing it
    # `dense` or `end` (the paper's memory); None: dense for a new memory, the memory's own with `add_to`
    failure_frames: str | None = None
    # `change` or `concat` (the paper's pairing); None: change for a new memory, the memory's own with `add_to`
    pairing: str | None = None
    # the robot's signals beside the cameras: `auto`, `none` or names; None: auto (with `add_to`: the memory's)
    signals: str | None = None
    # features derived from the signals: `change`, `events`, both or `none`; None: both (with `add_to`: the memory's)
    signal_features: str | None = None
    ray: str | None = None  # a Ray cluster's address: frames decoded and encoded there (docs/ray.md)

    def __post_init__(self) -> None:  # a bad setting fails before anything is read
        self.recipe  # noqa: B018 (the recipe checks every setting)

    @property
    def recipe(self) -> MemoryRecipe:
        """The recipe of a new memory: the settings chosen, the recipe's defaults for the others (with
        `add_to` the grown memory keeps its own failure frames and pairing)."""
        return MemoryRecipe.chosen(
            self.encoder,
            failure_frames=self.failure_frames,
            pairing=self.pairing,
            success_step=self.success_step,
            signals=self.signals,
            signal_features=self.signal_features,
        )


def build_memory(config: BuildMemoryConfig) -> tuple[FailureMemory, BuildStats]:
    """Build a failure memory from a dataset's failure trajectories and save it.

    `stats.skipped_inputs` lists what under the dataset root was not read, with the reason. The
    output is checked (and locked against a second build) before anything is encoded; a build
    that would hold no entry is an error and replaces nothing. Data with success runs and no
    failure run gives a memory with an empty failure memory (the novelty rule judges its tasks).
    """
    if config.add_to and not is_memory_dir(config.out):
        raise MemoryFormatError(
            f"--add-to {config.out} is not a failure memory (no manifest.json); nothing was written"
        )
    check_memory_target(config.out, inputs=[config.data])
    with output_lock(config.out):
        return _add_to_memory(config) if config.add_to else _build_memory(config)


def _build_memory(config: BuildMemoryConfig) -> tuple[FailureMemory, BuildStats]:
    vocabulary = read_vocabulary(config.vocabulary) if config.vocabulary is not None else None
    encoder = open_encoder(
        config.encoder,
        device=config.device,
        cache_dir=config.cache_dir,
        runtime=config.runtime,
        ray=config.ray,
    )
    dataset = load_dataset(
        config.data, task=config.task, labels=config.labels, views=config.views, vocabulary=vocabulary
    )
    dataset.require_labels("build-memory")
    trajectories = _selected(config, dataset)
    where = f"{config.data}{f' (split {config.split})' if config.split else ''}"
    failures = sum(1 for t in trajectories if is_failure(t))
    successes = sum(1 for t in trajectories if t.outcome is Outcome.SUCCESS)
    if not failures and not (config.successes and successes):
        raise DataError(
            f"{where} holds no failure trajectory among its {len(trajectories)}"
            + (
                " and --no-successes leaves out its success runs: a memory needs one or the other"
                if successes
                else " and no success run: a memory needs one or the other"
            )
            + "; nothing was written"
        )
    provenance = Provenance(
        data=Path(config.data),
        encoder=config.encoder,
        layout=dataset.layout,
        views=dataset.views,
        split=config.split,
        skipped_inputs=dataset.skipped,
    )
    memory, stats = build_memories(
        trajectories,
        encoder,
        provenance=provenance,
        recipe=config.recipe,
        successes=config.successes,
        vocabulary=vocabulary,
    )
    if not len(memory) and memory.successes is None:
        raise DataError(
            f"no memory entry from {config.data}: every view has fewer than 2 frames; nothing was written"
        )
    success_only = [task for task in memory.tasks if not memory.has_failures(task)]
    if success_only:
        stats.notes.append(
            f"no failure run of {', '.join(success_only)}: judged by the novelty rule (N_t = 1 − S⁺_t ≥ η) "
            "until failure runs are added; calibrate η with `robofailring calibrate`"
        )
    stats.notes.extend(_dropped_calibration(config.out))
    memory.save(config.out)
    return memory, stats


def _add_to_memory(config: BuildMemoryConfig) -> tuple[FailureMemory, BuildStats]:
    """The memory at `config.out` grown by the dataset's runs, saved in its place (atomically)."""
    memory = FailureMemory.load(config.out)
    held = memory.manifest.failure_mode
    if config.failure_frames not in (None, held):
        raise SettingError(
            f"--failure-frames {config.failure_frames} differs from the memory at {config.out}, which holds "
            f"{held} failure frames: a grown memory keeps its own (leave out --failure-frames, or rebuild)"
        )
    if config.pairing not in (None, memory.pairing):
        raise SettingError(
            f"--pairing {config.pairing} differs from the memory at {config.out}, which pairs frames by "
            f"{memory.pairing}: a grown memory keeps its own (leave out --pairing, or rebuild)"
        )
    if config.vocabulary is not None and read_vocabulary(config.vocabulary) != memory.vocabulary:
        raise SettingError(
            f"--vocabulary {config.vocabulary} differs from the vocabulary of the memory at {config.out}: "
            "a memory keeps the vocabulary it was built with (leave out --vocabulary, or rebuild)"
        )
    encoder = open_encoder(
        config.encoder,
        device=config.device,
        cache_dir=config.cache_dir,
        runtime=config.runtime,
        ray=config.ray,
    )
    dataset = load_dataset(config.data, task=config.task, labels=config.labels, vocabulary=memory.vocabulary)
    dataset.require_labels("build-memory --add-to")
    trajectories = _selected(config, dataset)
    if (
        config.labels is not None
    ):  # the runs a person labelled (`review --write-labels`), not the whole dataset
        labelled = read_labels(config.labels, vocabulary=memory.vocabulary)
        trajectories = [t for t in trajectories if label_key(t, labelled) is not None]
    if not any(t.outcome is not None for t in trajectories):
        raise DataError(f"{config.data} holds no labelled run to add; nothing was written")
    grown, stats = add_to(
        memory,
        trajectories,
        encoder,
        successes=config.successes,
        success_step=config.success_step,
        skipped_inputs=dataset.skipped,
    )
    stats.notes.extend(_dropped_calibration(config.out))
    grown.save(config.out)
    return grown, stats


def _selected(config: BuildMemoryConfig, dataset: Dataset) -> list[Trajectory]:
    """The trajectories of `config.split` (all of them without one); DataError naming the splits there are."""
    trajectories = list(dataset.trajectories())
    if config.split is None:
        return trajectories
    chosen = dataset.select(split=config.split)
    if not chosen:
        splits = sorted({str(t.split) for t in trajectories if t.split is not None})
        raise DataError(
            f"no trajectory of split {config.split!r} in {config.data}; its splits are: "
            + (", ".join(splits) or "none (this layout has no splits: leave out --split)")
        )
    return chosen


def _dropped_calibration(out: Path) -> list[str]:
    """A note when the memory being replaced had calibrated thresholds: they are not carried over.

    δ (or η, for a memory of success runs only) is chosen against the old memory's entries; new
    entries move every score, so a stale threshold would silently change the false-positive rate.
    Calibrate the new memory again.
    """
    if not is_memory_dir(out):
        return []
    try:
        old = FailureMemory.load(out)
    except MemoryFormatError:
        return []
    calibrated = {rule: old.calibrated_threshold(rule.name) for rule in RULES.values()}
    said = next(
        (f"{rule.symbol} = {value:.6f}" for rule, value in calibrated.items() if value is not None), None
    )
    if said is None:
        return []
    return [
        f"the memory replaced at {out} had a calibrated {said}; the new one is uncalibrated "
        f"(thresholds depend on the entries): run `robofailring calibrate DATA --memory {out}` again"
    ]
