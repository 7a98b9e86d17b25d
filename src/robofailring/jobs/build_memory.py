"""The build-memory job: a dataset's failure (and success) runs encoded into a memory folder."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from robofailring.atomic import output_lock
from robofailring.data.labels import label_key, read_labels
from robofailring.data.layouts import Dataset
from robofailring.data.model import Outcome, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.detection.rules import RULES
from robofailring.encoders.placement import DEFAULT_PLACEMENT, EncoderPlacement
from robofailring.errors import DataError, MemoryFormatError, SettingError
from robofailring.memory.builder import Provenance, add_to, build_memories
from robofailring.memory.encoding import BuildStats, is_failure
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import MemoryRecipe
from robofailring.outputs import check_memory_target, is_memory_dir


@dataclass(frozen=True)
class BuildMemoryConfig:
    data: DataSelection  # the dataset (any supported layout) and how it is read; its vocabulary is kept
    out: Path  # memory directory to write (atomically)
    # how the memory is made; with `add_to` the memory keeps its own, and a setting chosen that differs from
    # it (`MemoryRecipe.chosen`: the options given) is refused, but a chosen success step is used
    recipe: MemoryRecipe = field(default_factory=MemoryRecipe.chosen)
    # the device, runtime, cache and Ray cluster the recipe's encoder runs on (a memory is built, not judged)
    placement: EncoderPlacement = DEFAULT_PLACEMENT
    split: str | None = None  # only trajectories of this split (project layout)
    success_memory: bool = (
        True  # also build the success memory (contrast rule); False: the paper's memory alone
    )
    add_to: bool = False  # grow the memory at `out` with the dataset's runs instead of replacing it


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
    check_memory_target(config.out, inputs=[config.data.root])
    with output_lock(config.out):
        return _add_to_memory(config) if config.add_to else _build_memory(config)


def _build_memory(config: BuildMemoryConfig) -> tuple[FailureMemory, BuildStats]:
    vocabulary = config.data.read_vocabulary()
    encoder = config.placement.open(config.recipe.encoder)
    dataset = config.data.load(vocabulary=vocabulary)
    dataset.require_labels("build-memory")
    trajectories = _selected(config, dataset)
    where = f"{config.data.root}{f' (split {config.split})' if config.split else ''}"
    failures = sum(1 for t in trajectories if is_failure(t))
    successes = sum(1 for t in trajectories if t.outcome is Outcome.SUCCESS)
    if not failures and not (config.success_memory and successes):
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
        data=config.data.root,
        encoder=config.recipe.encoder,
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
        successes=config.success_memory,
        vocabulary=vocabulary,
    )
    if not len(memory) and memory.successes is None:
        raise DataError(
            f"no memory entry from {config.data.root}: every view has fewer than 2 frames; nothing was written"
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
    recipe, held = config.recipe, memory.manifest.failure_mode
    if recipe.was_given("failure_frames") and recipe.failure_frames != held:
        raise SettingError(
            f"--failure-frames {recipe.failure_frames} differs from the memory at {config.out}, which holds "
            f"{held} failure frames: a grown memory keeps its own (leave out --failure-frames, or rebuild)"
        )
    if recipe.was_given("pairing") and recipe.pairing != memory.pairing:
        raise SettingError(
            f"--pairing {recipe.pairing} differs from the memory at {config.out}, which pairs frames by "
            f"{memory.pairing}: a grown memory keeps its own (leave out --pairing, or rebuild)"
        )
    vocabulary = config.data.vocabulary
    if vocabulary is not None and config.data.read_vocabulary() != memory.vocabulary:
        raise SettingError(
            f"--vocabulary {vocabulary} differs from the vocabulary of the memory at {config.out}: "
            "a memory keeps the vocabulary it was built with (leave out --vocabulary, or rebuild)"
        )
    encoder = config.placement.open(recipe.encoder)
    # its labels read by the memory's vocabulary; `--views` is not applied to the runs added
    dataset = replace(config.data, views=None).load(vocabulary=memory.vocabulary)
    dataset.require_labels("build-memory --add-to")
    trajectories = _selected(config, dataset)
    labels = config.data.labels
    if labels is not None:  # the runs a person labelled (`review --write-labels`), not the whole dataset
        labelled = read_labels(labels, vocabulary=memory.vocabulary)
        trajectories = [
            t
            for t in trajectories
            if (key := label_key(t, labelled)) is not None and labelled[key].outcome is not None
        ]
    if not any(t.outcome is not None for t in trajectories):
        raise DataError(f"{config.data.root} holds no labelled run to add; nothing was written")
    grown, stats = add_to(
        memory,
        trajectories,
        encoder,
        successes=config.success_memory,
        success_step=recipe.success_step if recipe.was_given("success_step") else None,
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
            f"no trajectory of split {config.split!r} in {config.data.root}; its splits are: "
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
