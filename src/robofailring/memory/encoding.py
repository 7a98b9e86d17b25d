"""Algorithm 1 of the paper: each failure view's first and last frames encoded into one pair vector.

Both ways of building a failure memory use it: `FailureMemory.build` (the paper's memory alone)
and `robofailring.memory.builder.build_memories` (the complete memory a job saves).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

import numpy as np

from robofailring.data.grounding import Vocabulary, parse_symbol
from robofailring.data.model import Frame, Outcome, Skipped, Trajectory
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import SymbolError
from robofailring.memory.entry import MemoryEntry
from robofailring.memory.manifest import MemoryManifest
from robofailring.memory.pairs import pair_vectors
from robofailring.memory.references import absolute_reference


@dataclass
class BuildStats:
    """What building a memory took in and left out (skipped views are counted and reported)."""

    trajectories: int = 0
    failures: int = 0
    ignored_non_failures: int = 0  # success runs (labelled), which hold no failure entry
    unlabelled: int = 0  # runs whose outcome nothing gave (no labels row): neither failure nor success
    entries: int = 0
    skipped_views: list[dict[str, Any]] = field(default_factory=list)
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the dataset not read
    notes: list[str] = field(default_factory=list)  # said to the user after the build


@dataclass(frozen=True)
class EncodedFailures:
    """Algorithm 1's output before it is indexed: one pair vector and one entry per failure view."""

    vectors: np.ndarray
    entries: list[MemoryEntry]
    stats: BuildStats

    def manifest(self, encoder: str, **provenance: Any) -> MemoryManifest:
        """The manifest of a memory of these entries; `provenance`: its other fields (source, split, …)."""
        return MemoryManifest(
            encoder=encoder,
            dim=int(self.vectors.shape[1]),
            skipped_views=len(self.stats.skipped_views),
            skipped=self.stats.skipped_views,
            failures=self.stats.failures,
            ignored_non_failures=self.stats.ignored_non_failures,
            created=datetime.now(UTC).isoformat(timespec="seconds"),
            **provenance,
        )


def encode_failures(
    trajectories: Iterable[Trajectory],
    encoder: CachedEncoder,
    *,
    progress: Callable[[int], None] | None = None,
    vocabulary: Vocabulary | None = None,
) -> EncodedFailures:
    """Algorithm 1 over the failure trajectories; views with < 2 frames are skipped and counted.

    Symbols are validated first (Table 5 and `vocabulary`, the dataset's own symbols), so an unknown token fails the build before anything is encoded.
    `progress` is told how many entries each chunk encoded.
    """
    stats = BuildStats()
    pending: list[tuple[MemoryEntry, Frame, Frame]] = []
    for trajectory in trajectories:
        stats.trajectories += 1
        if not is_failure(trajectory):
            if trajectory.outcome is None:
                stats.unlabelled += 1
            else:
                stats.ignored_non_failures += 1
            continue
        stats.failures += 1
        if not trajectory.symbol:
            raise SymbolError(f"failure trajectory {trajectory.key} has no failure symbol")
        try:
            parse_symbol(trajectory.symbol, vocabulary)
        except SymbolError as error:
            raise SymbolError(f"trajectory {trajectory.key} ({trajectory.source}): {error}") from error
        for view, frames in trajectory.views.items():
            if len(frames) < 2:
                stats.skipped_views.append(
                    {"trajectory": trajectory.key, "view": view, "frames": len(frames)}
                )
                continue
            entry = MemoryEntry(
                task=trajectory.task,
                symbol=trajectory.symbol,
                episode=trajectory.episode,
                view=view,
                start=absolute_reference(frames[0].reference),
                end=absolute_reference(frames[-1].reference),
                written=trajectory.description,
                vocabulary=vocabulary,
            )
            pending.append((entry, frames[0], frames[-1]))
    vectors = np.zeros((0, encoder.dim * 2), dtype=np.float32)
    if pending:
        frames = [frame for _, start, end in pending for frame in (start, end)]
        embeddings = []
        for offset in range(0, len(frames), 256):
            chunk = frames[offset : offset + 256]
            embeddings.append(encoder.encode_frames(chunk))
            if progress is not None:
                progress(len(chunk) // 2)
        stacked = np.concatenate(embeddings)
        vectors = pair_vectors(stacked[0::2], stacked[1::2])
    stats.entries = len(pending)
    return EncodedFailures(vectors, [entry for entry, _, _ in pending], stats)


def is_failure(trajectory: Trajectory) -> bool:
    if trajectory.outcome is not None:
        return trajectory.outcome is Outcome.FAILURE
    return bool(trajectory.symbol)
