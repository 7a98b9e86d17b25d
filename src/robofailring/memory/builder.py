"""The one way a complete memory is built: failure entries, success runs and a manifest that says where they came from.

`build_memories` is what `build-memory` and `evaluate` use; it returns the memory finished, so
nothing sets its success memory or manifest fields afterwards. `add_to` grows a memory the same
way: it returns a new complete memory with the new runs added (`build-memory --add-to`), with the
memory's own failure frames (`end` or `dense`) and thinning step, so a grown memory stays one kind. (`FailureMemory.build` gives the
paper's memory alone, without success runs or provenance, for tests and benchmarks.)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from robofailring.data.grounding import Vocabulary
from robofailring.data.model import Skipped, Trajectory
from robofailring.encoders import portable_spec
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import DataError, EncoderMismatchError
from robofailring.memory.encoding import BuildStats, EncodedFailures, encode_failures, failure_views
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import DEFAULT_RECIPE, MemoryRecipe
from robofailring.memory.signals.layout import NONE
from robofailring.memory.signals.memory import SignalMemory
from robofailring.memory.success import SuccessMemory
from robofailring.progress import progress_bar


@dataclass(frozen=True)
class Provenance:
    """Where a memory's trajectories came from, as its manifest records it."""

    data: Path  # the dataset root: recorded as `source`, and the root references are stored under
    encoder: str  # the encoder spec the memory was built with (recorded portable, to reopen it)
    layout: str | None = None  # the dataset's layout
    views: Sequence[str] | None = None  # the views read from it (after `--views`)
    split: str | None = None  # the split the trajectories were taken from (None: all of them)
    skipped_inputs: Sequence[Skipped] = ()  # folders and files of the dataset that were not read


def build_memories(
    trajectories: Sequence[Trajectory],
    encoder: CachedEncoder,
    *,
    provenance: Provenance,
    recipe: MemoryRecipe = DEFAULT_RECIPE,
    successes: bool = True,
    vocabulary: Vocabulary | None = None,
) -> tuple[FailureMemory, BuildStats]:
    """The failure memory of the failure `trajectories` with, when `successes`, the success memory of all of them.

    `recipe` (`robofailring.memory.recipe`): its failure frames, `dense` (each failure view's frames from
    its onset on, thinned at its step) or `end` (the paper's one entry per view), and its pairing, for both
    memories, and which of the robot's signals make the signal memory (`robofailring.memory.signals.memory`;
    none where no run has them). A dataset without a success run gives no success memory.
    Image references are kept relative to the dataset root. `stats.skipped_inputs` (the provenance's, the blank
    frames not stored, the runs whose signals were not used) is kept in the manifest's `skipped_inputs`.
    `vocabulary` (the dataset's own symbols beyond Table 5) is kept with the memory.
    """
    root = Path(provenance.data).resolve()
    encoded, built = _encode(
        trajectories,
        encoder,
        successes=successes,
        recipe=recipe,
        failure_step=recipe.success_step,
        vocabulary=vocabulary,
    )
    success_memory = built if built is not None and built.success_runs else None  # none: the paper's memory
    signals, unused = (
        SignalMemory.build(
            trajectories,
            choice=recipe.signals,
            features=recipe.signal_features,
            start_weight=recipe.signal_start_weight,
        )
        if recipe.signals != NONE
        else (None, [])
    )
    encoded.stats.skipped_inputs = [*provenance.skipped_inputs, *encoded.stats.skipped_inputs, *unused]
    manifest = encoded.manifest(
        encoder.identity,
        skipped_inputs=[skipped.to_dict() for skipped in encoded.stats.skipped_inputs],  # all it listed
        source=str(root),
        layout=provenance.layout,
        data_views=list(provenance.views) if provenance.views is not None else None,
        encoder_spec=portable_spec(provenance.encoder),
        split=provenance.split,
        data_root=str(root),
    )
    memory = FailureMemory(
        encoded.vectors,
        encoded.entries,
        encoder=encoder.identity,
        manifest=replace(manifest, signals=signals.manifest() if signals is not None else None),
        data_root=root,
        successes=success_memory,
        vocabulary=vocabulary,
        signals=signals,
    )
    return memory, encoded.stats


def add_to(
    memory: FailureMemory,
    trajectories: Sequence[Trajectory],
    encoder: CachedEncoder,
    *,
    successes: bool = True,
    success_step: float | None = None,
    skipped_inputs: Sequence[Skipped] = (),
) -> tuple[FailureMemory, BuildStats]:
    """A new complete memory: `memory` with the failure (and, when `successes`, success) runs of `trajectories` added.

    The same encoder is required (EncoderMismatchError) and an episode the memory already holds is
    refused (DataError), both before anything is encoded. The memory keeps its data root,
    provenance and vocabulary (new symbols are checked against it); its stored calibration is
    dropped, as a rebuild's is: thresholds depend on the entries.
    """
    if encoder.identity != memory.encoder:
        raise EncoderMismatchError(
            f"the memory was built with encoder {memory.encoder!r}, the runs to add would be encoded with "
            f"{encoder.identity!r}: add with --encoder {memory.manifest.encoder_spec or memory.encoder}"
        )
    held = {(e.task, e.episode) for e in memory.entries}
    if memory.successes is not None:
        held |= {(run.task, run.episode) for run in memory.successes.runs}
    repeated = sorted(f"{t.task}/{t.episode}" for t in trajectories if (t.task, t.episode) in held)
    if repeated:
        raise DataError(
            f"the memory already holds episode {repeated[0]!r}"
            + (f" and {len(repeated) - 1} more" if len(repeated) > 1 else "")
            + "; add only new episodes (or rebuild the memory)"
        )
    old = memory.manifest
    recipe = memory.recipe if success_step is None else replace(memory.recipe, success_step=success_step)
    encoded, new_successes = _encode(
        trajectories,
        encoder,
        successes=successes,
        recipe=recipe,
        failure_step=old.failure_step if old.failure_step is not None else recipe.success_step,
        vocabulary=memory.vocabulary,
    )
    signals, unused = (
        memory.signals.extended(trajectories) if memory.signals is not None else (None, list[Skipped]())
    )
    joined = memory.successes
    if new_successes is not None and len(new_successes):
        if joined is not None:
            joined = joined.extended(new_successes)
        elif new_successes.success_runs:
            joined = new_successes
    stats = encoded.stats
    stats.skipped_inputs = [*skipped_inputs, *stats.skipped_inputs, *unused]
    manifest = replace(
        old,
        failures=(old.failures or 0) + stats.failures,
        ignored_non_failures=(old.ignored_non_failures or 0) + stats.ignored_non_failures,
        skipped_views=(old.skipped_views or 0) + len(stats.skipped_views),
        skipped=[*(old.skipped or []), *stats.skipped_views],
        skipped_inputs=[*(old.skipped_inputs or []), *(s.to_dict() for s in stats.skipped_inputs)],
        calibration=None,
        signals=signals.manifest() if signals is not None else None,
    )
    grown = FailureMemory(
        np.concatenate([memory.vectors, encoded.vectors]) if len(encoded.vectors) else memory.vectors,
        [*memory.entries, *encoded.entries],
        encoder=memory.encoder,
        manifest=manifest,
        data_root=memory.data_root,
        successes=joined,
        vocabulary=memory.vocabulary,
        signals=signals,
    ).derived_from(memory)  # saved over `memory`'s folder only while that is still the version read
    return grown, stats


def _encode(
    trajectories: Sequence[Trajectory],
    encoder: CachedEncoder,
    *,
    successes: bool,
    recipe: MemoryRecipe,
    failure_step: float,
    vocabulary: Vocabulary | None,
) -> tuple[EncodedFailures, SuccessMemory | None]:
    """The failure memory's entries and, when `successes`, the success memory of all `trajectories`."""
    planned = failure_views(trajectories, failure_frames=recipe.failure_frames, vocabulary=vocabulary)
    with progress_bar(total=planned.frames, desc="encoding memory", unit="frame") as bar:
        encoded = encode_failures(
            planned, encoder, step=failure_step, pairing=recipe.pairing, progress=bar.update
        )
    if not successes:
        return encoded, None
    with progress_bar(total=len(trajectories), desc="encoding success memory", unit="traj") as bar:
        built = SuccessMemory.build(
            trajectories,
            encoder,
            step=recipe.success_step,
            pairing=recipe.pairing,
            progress=bar.update,
            skipped=encoded.stats.skipped_inputs,  # blank frames, listed with the failure memory's
        )
    return encoded, built
