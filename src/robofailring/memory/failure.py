"""The failure memory (paper §3.2, Algorithm 1): start‖end vectors per failure view, in Faiss."""

from __future__ import annotations

import copy
import json
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from datetime import UTC, datetime
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from robofailring.atomic import atomic_directory, output_lock, write_text_atomic
from robofailring.data.grounding import Vocabulary
from robofailring.data.model import Trajectory
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import EncoderMismatchError, MemoryFormatError, UnknownTaskError
from robofailring.memory.encoding import BuildStats, encode_failures, failure_views
from robofailring.memory.entry import MemoryEntry, Neighbor
from robofailring.memory.folder import (
    FORMAT_VERSION,
    MANIFEST,
    VOCABULARY,
    read_memory_files,
    write_memory_files,
)
from robofailring.memory.image_roots import ImageRoots
from robofailring.memory.index import FLAT, TaskIndexSet
from robofailring.memory.manifest import MemoryManifest
from robofailring.memory.pairs import pair_vectors
from robofailring.memory.recipe import MemoryRecipe
from robofailring.memory.references import (
    ReferenceCheck,
    check_references,
    storage_root,
)
from robofailring.memory.signals.memory import SignalMemory
from robofailring.memory.signals.modality import BOTH
from robofailring.memory.stored_calibration import StoredCalibration
from robofailring.memory.version import ReadFrom, read_whole, refuse_stale, require_read_from
from robofailring.outputs import check_memory_target

if TYPE_CHECKING:
    from robofailring.memory.success import SuccessMemory


class FailureMemory:
    """Memory vectors plus metadata, searchable top-K within one task."""

    def __init__(
        self,
        vectors: np.ndarray,
        entries: Sequence[MemoryEntry],
        *,
        encoder: str,
        manifest: MemoryManifest | None = None,
        data_root: Path | None = None,
        successes: SuccessMemory | None = None,
        vocabulary: Vocabulary | None = None,
        signals: SignalMemory | None = None,
        image_roots: ImageRoots | None = None,
    ) -> None:
        vectors = np.ascontiguousarray(vectors, dtype=np.float32)
        if vectors.ndim != 2 or len(vectors) != len(entries):
            raise MemoryFormatError(f"{len(entries)} entries but vectors of shape {vectors.shape}")
        self.vectors = vectors
        self.vocabulary = vocabulary  # the memory's own symbols beyond Table 5 (saved as vocabulary.json)
        self.entries = [  # every entry grounds with the memory's vocabulary
            entry if entry.vocabulary is vocabulary else replace(entry, vocabulary=vocabulary)
            for entry in entries
        ]
        self.encoder = encoder
        self.dim = int(vectors.shape[1]) if vectors.size else (manifest.dim if manifest is not None else 0)
        self.manifest = manifest if manifest is not None else MemoryManifest(encoder=encoder, dim=self.dim)
        self.data_root = Path(data_root).resolve() if data_root is not None else None
        # where its images may be read from: a memory built here, its data; one loaded, the folders named (`load`)
        self.image_roots = image_roots if image_roots is not None else ImageRoots.of(self.data_root)
        self.successes = successes  # success runs for the contrast rule (robofailring.memory.success)
        self.signals = (
            signals  # the robot's signals as a second modality (robofailring.memory.signals.memory)
        )
        # the folder this memory (or the one it was derived from) was read from, and that folder's
        # version then: writing back over it is refused once another process has replaced it
        self.read_from: ReadFrom | None = None
        self.index = TaskIndexSet.build(  # exact search: a failure memory is small (docs/scale.md)
            vectors, [e.task for e in self.entries], [e.episode for e in self.entries], kind=FLAT
        )

    # ---------------------------------------------------------------- building
    @classmethod
    def build(
        cls,
        trajectories: Iterable[Trajectory],
        encoder: CachedEncoder,
        *,
        progress: Callable[[int], None] | None = None,
        data_root: Path | None = None,
        vocabulary: Vocabulary | None = None,
    ) -> tuple[FailureMemory, BuildStats]:
        """The paper's memory alone (Algorithm 1: one end entry per failure view), without success runs
        or provenance; `progress` is told the frames encoded.

        `robofailring.memory.builder.build_memories` builds the complete memory a job saves.
        Image references are kept relative to `data_root` when saved (default: the folder that
        holds all of them), so the memory resolves from any working directory.
        """
        paper = MemoryRecipe.paper(encoder.identity)
        planned = failure_views(trajectories, failure_frames=paper.failure_frames, vocabulary=vocabulary)
        encoded = encode_failures(
            planned, encoder, step=paper.success_step, pairing=paper.pairing, progress=progress
        )
        memory = cls(
            encoded.vectors,
            encoded.entries,
            encoder=encoder.identity,
            manifest=encoded.manifest(encoder.identity),
            data_root=data_root,
            vocabulary=vocabulary,
        )
        return memory, encoded.stats

    # ---------------------------------------------------------------- queries
    @property
    def recipe(self) -> MemoryRecipe:
        """How the memory was made (`robofailring.memory.recipe`), read from its manifest."""
        return MemoryRecipe.of(self.manifest)

    @property
    def pairing(self) -> str:
        """How it pairs a first and a current frame, queries alike: `concat` (the paper's) or `change`."""
        return self.manifest.pairing_mode

    def pair(self, first: np.ndarray, current: np.ndarray) -> np.ndarray:
        """Queries of this memory, paired as its entries are: a first frame's embedding (d,) with each of
        (N, d) current ones -> (N, 2d) unit rows."""
        current = np.atleast_2d(current)
        return pair_vectors(
            np.repeat(np.atleast_2d(first), len(current), axis=0), current, pairing=self.pairing
        )

    @property
    def tasks(self) -> list[str]:
        """Every task the memory knows: those with failure entries and those with success runs only."""
        known = set(self.index.tasks) | set(self.successes.tasks if self.successes is not None else ())
        return sorted(known)

    def __len__(self) -> int:
        return len(self.entries)

    def task_size(self, task: str) -> int:
        """Failure entries of `task` (0 for a task with success runs only); UnknownTaskError for another."""
        self._check_task(task)
        return self.index.by_task[task].size if task in self.index.by_task else 0

    def has_failures(self, task: str) -> bool:
        """Whether `task` has failure entries (a task with success runs only has none)."""
        return task in self.index.by_task

    def check_encoder(self, identity: str) -> None:
        """Raise EncoderMismatchError unless `identity` is the encoder that built the memory."""
        if identity != self.encoder:
            raise EncoderMismatchError(
                f"this memory was built with encoder {self.encoder!r} but is queried with {identity!r}; "
                "rebuild the memory with the same encoder or query with the one that built it"
            )

    def _check_task(self, task: str) -> None:
        if task not in self.index.by_task and not (
            self.successes is not None and self.successes.has_task(task)
        ):
            known = ", ".join(self.tasks[:20]) + (" …" if len(self.tasks) > 20 else "")
            raise UnknownTaskError(f"task {task!r} has no entry in the memory; its tasks are: {known}")

    def search(
        self, queries: np.ndarray, task: str, k: int, *, exclude_episode: str | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Top-`k` entries of `task` for each query row (eq. 5).

        Returns (similarities, global ids), both (n, k); rows are padded with NaN and -1 when the
        task has fewer than k usable entries (all of them for a task with success runs only).
        `exclude_episode` hides that episode's entries (leave-one-out). All query rows (e.g. the
        views of one step) go to Faiss in one call.
        """
        queries = np.ascontiguousarray(np.atleast_2d(queries), dtype=np.float32)
        if queries.shape[1] != self.dim:
            raise MemoryFormatError(f"query dimension {queries.shape[1]} != memory dimension {self.dim}")
        self._check_task(task)
        if not self.has_failures(task):
            return np.full((len(queries), k), np.nan, np.float32), np.full((len(queries), k), -1, np.int64)
        return self.index.search(queries, task, k, exclude_episode=exclude_episode)

    def own_episode(
        self, task: str, starts: Iterable[str], *, exclude_episode: str | None = None
    ) -> str | None:
        """The memory's episode of `task` that starts at one of `starts` (a trajectory's first frame per
        view, as absolute references), or None: a trajectory of the memory's own data meets itself.

        Its failure entries and success runs count (leave-one-out hides `exclude_episode`'s). Frames, not
        names, decide: a new dataset reuses episode names (`pick_cube_success_episode0`).
        """
        for start in starts:
            for episode in self._episodes_by_start.get((task, start), ()):
                if episode != exclude_episode:
                    return episode
        return None

    @cached_property
    def _episodes_by_start(self) -> dict[tuple[str, str], set[str]]:
        """(task, first-frame reference) -> episodes, over failure entries and success runs."""
        found: dict[tuple[str, str], set[str]] = {}
        runs = self.successes.runs if self.successes is not None else []
        starts = [(e.task, e.start, e.episode) for e in self.entries]
        for task, start, episode in starts + [(r.task, r.frames[0], r.episode) for r in runs if r.frames]:
            found.setdefault((task, start), set()).add(episode)
        return found

    def neighbors(self, similarities: np.ndarray, ids: np.ndarray) -> list[Neighbor]:
        """Neighbour objects for one row of a search result."""
        return [
            Neighbor(index=int(i), similarity=float(s), entry=self.entries[int(i)])
            for s, i in zip(similarities, ids, strict=True)
            if i >= 0
        ]

    # ---------------------------------------------------------------- storage
    def save(self, directory: Path) -> Path:
        """Write index, entries and manifest as one directory, atomically.

        Only an absent or empty folder, or another memory, is replaced (OutputError otherwise).
        The memory itself is not changed: references are written relative to its data root
        (default: the folder that holds all of them), which the written manifest records.
        """
        directory = Path(directory)
        check_memory_target(directory)
        runs = self.successes.runs if self.successes is not None else []
        root = storage_root(
            self.data_root,
            [
                *(ref for entry in self.entries for ref in (entry.start, entry.end)),
                *(frame for run in runs for frame in run.frames),
            ],
        )
        manifest = self._full_manifest()
        if root is not None:
            manifest = replace(manifest, data_root=str(root))
        with atomic_directory(directory) as tmp:
            refuse_stale(self.read_from, directory)
            write_memory_files(
                tmp,
                vectors=self.vectors,
                dim=self.dim,
                entries=self.entries,
                root=root,
                successes=self.successes,
                signals=self.signals,
                vocabulary=self.vocabulary,
                manifest=manifest,
            )
        return directory

    def _full_manifest(self) -> MemoryManifest:
        return replace(
            self.manifest,
            format_version=FORMAT_VERSION,
            encoder=self.encoder,
            dim=self.dim,
            count=len(self.entries),
            tasks=dict(sorted(Counter(e.task for e in self.entries).items())),
            views=sorted({e.view for e in self.entries}),
            symbols=dict(sorted(Counter(e.symbol for e in self.entries).items())),
            vocabulary=VOCABULARY if self.vocabulary is not None else None,
            successes=self.successes.manifest() if self.successes is not None else None,
            signals=self.signals.manifest() if self.signals is not None else None,
            created=self.manifest.created or datetime.now(UTC).isoformat(timespec="seconds"),
        )

    def with_calibration(self, calibration: StoredCalibration) -> FailureMemory:
        """This memory with `calibration` as its stored thresholds (the same entries and indexes)."""
        return self._with(manifest=replace(self.manifest, calibration=calibration))

    def with_successes(self, successes: SuccessMemory | None) -> FailureMemory:
        """This memory with another success memory (e.g. with runs seen in deployment added)."""
        return self._with(successes=successes)

    def with_signals(self, signals: SignalMemory | None) -> FailureMemory:
        """This memory with another signal memory (e.g. with runs seen in deployment added)."""
        return self._with(signals=signals)

    def _with(self, **changed: Any) -> FailureMemory:
        other = copy.copy(self)  # entries, vectors and indexes are shared: none is changed in place
        other.__dict__.pop("_episodes_by_start", None)  # its successes may change
        other.__dict__.update(changed)
        return other

    def write_manifest(self, directory: Path) -> None:
        """Rewrite only the manifest of a saved memory (e.g. after calibration), atomically. The memory must have been read from `directory`, and the folder must still be the version it
        read: never while another process replaces that memory, nor after another process grew,
        rebuilt or recalibrated it (OutputBusyError then, and nothing is written).
        """
        with output_lock(directory):
            require_read_from(self.read_from, directory)
            write_text_atomic(
                Path(directory) / MANIFEST, json.dumps(self._full_manifest().to_dict(), indent=2)
            )

    def derived_from(self, other: FailureMemory) -> FailureMemory:
        """This memory, marked as a new version of the folder `other` was read from (see `save`)."""
        self.read_from = other.read_from
        return self

    @classmethod
    def load(
        cls, directory: Path, *, data_root: Path | None = None, trusted: Iterable[Path] = ()
    ) -> FailureMemory:
        """Read a saved memory; `data_root` re-roots its image references when the data moved. Its images
        are read only from under `data_root`, its own folder and the `trusted` folders (the data a job reads).
        A memory replaced by another process while it is read is read again (three tries), so the
        result is always one version of the folder, which it remembers (`read_from`)."""
        roots = ImageRoots.of(directory, data_root, *trusted)
        memory, read_from = read_whole(Path(directory), lambda folder: cls._read(folder, data_root, roots))
        memory.read_from = read_from
        return memory

    @classmethod
    def _read(cls, directory: Path, data_root: Path | None, image_roots: ImageRoots) -> FailureMemory:
        stored = read_memory_files(directory, data_root)
        return cls(
            stored.vectors,
            stored.entries,
            encoder=stored.manifest.encoder,
            manifest=stored.manifest,
            data_root=stored.data_root,
            successes=stored.successes,
            vocabulary=stored.vocabulary,
            signals=stored.signals,
            image_roots=image_roots,
        )

    def check_references(self, *, read: bool = False) -> ReferenceCheck:
        """Which entry images exist (`read`: and which lie outside `image_roots`, for a verb reading them)."""
        references = [ref for entry in self.entries for ref in (entry.start, entry.end)]
        found = check_references(references)
        return replace(found, outside=tuple(self.image_roots.outside(references))) if read else found

    # ---------------------------------------------------------------- calibration
    def calibrated_threshold(self, rule: str, modality: str = BOTH) -> float | None:
        """The rule named `rule`'s stored threshold for this memory's encoder and `modality`, if any."""
        calibration = self.manifest.calibration
        return calibration.threshold_for(self.encoder, rule, modality) if calibration is not None else None
