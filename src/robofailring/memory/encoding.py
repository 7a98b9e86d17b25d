"""Algorithm 1 of the paper: each failure view's first and last frames encoded into one pair vector,
and the dense memory: also (I_0 ‖ I_τ) for the frames from the failure's onset on, thinned.

Both ways of building a failure memory use it: `FailureMemory.build` (the paper's memory alone)
and `robofailring.memory.builder.build_memories` (the complete memory a job saves). First
`failure_views` picks the frames of each failure view (and checks every symbol), then
`encode_failures` encodes them, a chunk of frames at a time, into entries.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from itertools import islice
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.grounding import Vocabulary, parse_symbol
from robofailring.data.model import Frame, Outcome, Skipped, Trajectory
from robofailring.encoders.base import BLANK_REASON, frame_ranges, unusable
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import SymbolError
from robofailring.memory.entry import DENSE, END, MemoryEntry, check_failure_frames
from robofailring.memory.manifest import MemoryManifest
from robofailring.memory.pairs import check_pairing, pair_vectors
from robofailring.memory.references import absolute_reference
from robofailring.memory.thinning import check_step, thin_run

CHUNK_FRAMES: Final[int] = 256  # frames decoded and encoded per call, across the views


@dataclass
class BuildStats:
    """What building a memory took in and left out (skipped views are counted and reported)."""

    trajectories: int = 0
    failures: int = 0
    ignored_non_failures: int = 0  # success runs (labelled), which hold no failure entry
    unlabelled: int = 0  # runs whose outcome nothing gave (no labels row): neither failure nor success
    entries: int = 0
    views: int = 0  # failure views encoded
    offered: int = 0  # their frames paired with the first frame (one per view in the paper's memory)
    skipped_views: list[dict[str, Any]] = field(default_factory=list)
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the dataset not read
    notes: list[str] = field(default_factory=list)  # said to the user after the build


@dataclass(frozen=True)
class EncodedFailures:
    """Algorithm 1's output before it is indexed: a pair vector and an entry per failure view (per kept
    frame of each failure view, in a dense memory)."""

    vectors: np.ndarray
    entries: list[MemoryEntry]
    stats: BuildStats
    failure_frames: str  # `end` or `dense` (robofailring.memory.entry)
    step: float | None  # the dense memory's thinning step
    pairing: str  # how first and current frames were paired (robofailring.memory.pairs)

    def manifest(self, encoder: str, **provenance: Any) -> MemoryManifest:
        """The manifest of a memory of these entries; `provenance`: its other fields (source, split, …)."""
        return MemoryManifest(
            encoder=encoder,
            dim=int(self.vectors.shape[1]),
            failure_frames=self.failure_frames,
            failure_step=self.step,
            pairing=self.pairing,
            skipped_views=len(self.stats.skipped_views),
            skipped=self.stats.skipped_views,
            failures=self.stats.failures,
            ignored_non_failures=self.stats.ignored_non_failures,
            created=datetime.now(UTC).isoformat(timespec="seconds"),
            **provenance,
        )


@dataclass(frozen=True)
class FailureView:
    """One view of a failure run to encode: its entry (the end frame still to choose), its frames, and
    the frames τ to pair with its first."""

    entry: MemoryEntry
    frames: Sequence[Frame]
    candidates: range

    def to_encode(self) -> Iterator[Frame]:
        yield self.frames[0]
        yield from (self.frames[t] for t in self.candidates)


@dataclass(frozen=True)
class FailureViews:
    """The failure views of a set of trajectories with the frames each will pair (`failure_views`)."""

    views: list[FailureView]
    stats: BuildStats
    failure_frames: str

    @property
    def frames(self) -> int:
        """Frames to encode: each view's first and its candidates."""
        return sum(1 + len(view.candidates) for view in self.views)


def candidate_frames(length: int, onset: int | None, failure_frames: str) -> range:
    """The frames τ a failure view of `length` (≥ 2) frames pairs with its first: its last (`end`), or every
    frame from the onset on (`dense`; from frame 1 when the onset is unknown: frame 0 paired with itself is
    the success memory's, as the run's failure start)."""
    if failure_frames == END:
        return range(length - 1, length)
    return range(min(max(onset or 1, 1), length - 1), length)


def failure_views(
    trajectories: Iterable[Trajectory], *, failure_frames: str, vocabulary: Vocabulary | None = None
) -> FailureViews:
    """The views of the failure trajectories to encode; views with < 2 frames are skipped and counted.

    Symbols are validated here (Table 5 and `vocabulary`, the dataset's own symbols), so an unknown token
    fails the build before anything is encoded.
    """
    check_failure_frames(failure_frames)
    stats = BuildStats()
    views: list[FailureView] = []
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
            candidates = candidate_frames(len(frames), trajectory.onset_frame, failure_frames)
            views.append(FailureView(entry, frames, candidates))
    return FailureViews(views, stats, failure_frames)


def encode_failures(
    planned: FailureViews,
    encoder: CachedEncoder,
    *,
    step: float,
    pairing: str,
    progress: Callable[[int], None] | None = None,
) -> EncodedFailures:
    """The entries of the planned views: per view, its candidates paired with its first frame and thinned
    (`thinning.thin_run` at `step`, starting from the first frame paired with itself, so a candidate
    that has not yet moved away from the start is not kept: it would match every run's first frame;
    the last frame is always kept), one entry per frame kept.

    Frames are decoded CHUNK_FRAMES at a time, and a view's embeddings are let go once it is paired.
    `progress` is told how many frames each chunk encoded. The paper's memory (`end`) has one entry
    per view, without a frame number. An encoder whose backend works ahead (Ray, docs/ray.md) is
    first handed every frame to encode, in one pass, and the chunks then read them from its cache.
    """
    check_step(step)
    check_pairing(pairing)
    dense = planned.failure_frames == DENSE
    encoder.prefetch(frame for view in planned.views for frame in view.to_encode())  # ahead: one pass
    stats = replace(planned.stats)  # the plan's counts, with what encoding adds
    entries: list[MemoryEntry] = []
    vectors: list[np.ndarray] = []
    for view, embeddings in _embedded(planned.views, encoder, progress):
        blank = unusable(embeddings)
        if blank.any():  # a frame the encoder sees as nothing is never stored: it would match anything
            stats.skipped_inputs.append(_blank_skipped(view, blank))
            if blank[0]:
                continue
        paired = pair_vectors(
            np.repeat(embeddings[:1], len(embeddings), axis=0), embeddings, pairing=pairing
        )  # row 0: the first frame paired with itself, the state before anything happened
        usable = np.flatnonzero(~blank)
        kept = usable[thin_run(paired[usable], step=step).kept[1:]]  # a frame must differ from it to be kept
        vectors.append(paired[kept])
        for row in (kept - 1).tolist():
            frame = view.candidates[row]
            entries.append(
                replace(
                    view.entry,
                    end=absolute_reference(view.frames[frame].reference),
                    frame=frame if dense else None,
                    length=len(view.frames) if dense else None,
                )
            )
        stats.views += 1
        stats.offered += len(view.candidates)
    stats.entries = len(entries)
    stacked = np.concatenate(vectors) if vectors else np.zeros((0, encoder.dim * 2), dtype=np.float32)
    return EncodedFailures(stacked, entries, stats, planned.failure_frames, step if dense else None, pairing)


def _blank_skipped(view: FailureView, blank: np.ndarray) -> Skipped:
    """What a failure view's blank frames (`blank`: its first frame, then its candidates) cost the memory."""
    entry = view.entry
    where = Path(absolute_reference(view.frames[0].reference)).parent
    if blank[0]:
        why = f"its first frame is {BLANK_REASON}: the view is not in the memory"
    else:
        frames = [view.candidates[i - 1] for i in np.flatnonzero(blank)]
        why = f"frame(s) {frame_ranges(frames)} of {len(view.frames)} are {BLANK_REASON}"
    return Skipped(where, f"{entry.task}/{entry.episode} view {entry.view}: {why}", entry.view)


def _embedded(
    views: Sequence[FailureView], encoder: CachedEncoder, progress: Callable[[int], None] | None
) -> Iterator[tuple[FailureView, np.ndarray]]:
    """Each view with the embeddings of its first frame and its candidates, in order, encoded
    CHUNK_FRAMES frames at a time across views."""
    stream = ((position, frame) for position, view in enumerate(views) for frame in view.to_encode())
    parts: dict[int, list[np.ndarray]] = {}
    while chunk := list(islice(stream, CHUNK_FRAMES)):
        embeddings = encoder.encode_frames([frame for _, frame in chunk])
        if progress is not None:
            progress(len(chunk))
        positions = np.asarray([position for position, _ in chunk])
        for position in dict.fromkeys(positions.tolist()):
            parts.setdefault(position, []).append(embeddings[positions == position])
        last = int(positions[-1])
        for position in [p for p in parts if p < last]:  # the stream has moved past these views
            yield views[position], np.concatenate(parts.pop(position))
    for position in sorted(parts):
        yield views[position], np.concatenate(parts.pop(position))


def is_failure(trajectory: Trajectory) -> bool:
    if trajectory.outcome is not None:
        return trajectory.outcome is Outcome.FAILURE
    return bool(trajectory.symbol)
