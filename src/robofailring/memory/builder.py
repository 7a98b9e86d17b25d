"""The one way a complete memory is built: failure entries, success runs and a manifest that says where they came from.

`build_memories` is what `build-memory` and `evaluate` use; it returns the memory finished, so
nothing sets its success memory or manifest fields afterwards. (`FailureMemory.build` gives the
paper's memory alone, without success runs or provenance, for tests and benchmarks.)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from robofailring.data.model import Skipped, Trajectory
from robofailring.encoders import portable_spec
from robofailring.encoders.cache import CachedEncoder
from robofailring.memory.encoding import BuildStats, encode_failures, is_failure
from robofailring.memory.failure import FailureMemory
from robofailring.memory.success import SuccessMemory
from robofailring.memory.thinning import DEFAULT_STEP
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
    successes: bool = True,
    success_step: float = DEFAULT_STEP,
) -> tuple[FailureMemory, BuildStats]:
    """The failure memory of the failure `trajectories` with, when `successes`, the success memory of all of them.

    A dataset without a success run gives the paper's memory alone (no success memory). Image
    references are kept relative to the dataset root. `stats.skipped_inputs` is the provenance's.
    """
    root = Path(provenance.data).resolve()
    total = sum(len(t.views) for t in trajectories if is_failure(t))
    with progress_bar(total=total, desc="encoding memory", unit="entry") as bar:
        encoded = encode_failures(trajectories, encoder, progress=bar.update)
    success_memory = None
    if successes:
        with progress_bar(total=len(trajectories), desc="encoding success memory", unit="traj") as bar:
            built = SuccessMemory.build(trajectories, encoder, progress=bar.update, step=success_step)
        success_memory = built if built.success_runs else None  # none: the paper's memory
    manifest = encoded.manifest(
        encoder.identity,
        skipped_inputs=[skipped.to_dict() for skipped in provenance.skipped_inputs],
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
        manifest=manifest,
        data_root=root,
        successes=success_memory,
    )
    encoded.stats.skipped_inputs = list(provenance.skipped_inputs)
    return memory, encoded.stats
