"""The failure memory (paper §3.2, Algorithm 1): start‖end vectors per failure view, in Faiss."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import faiss
import numpy as np

from robofailring.atomic import atomic_directory, output_lock, restore_interrupted, write_text_atomic
from robofailring.data.grounding import ground, parse_symbol
from robofailring.data.model import Frame, Outcome, Skipped, Trajectory
from robofailring.encoders.cache import CachedEncoder
from robofailring.encoders.spec import EncoderSpec
from robofailring.errors import (
    EncoderMismatchError,
    MemoryFormatError,
    SymbolError,
    UnknownTaskError,
)
from robofailring.memory.format import parse_entry
from robofailring.memory.index import FLAT, IndexSpec, TaskIndex
from robofailring.memory.manifest import MemoryManifest
from robofailring.memory.pairs import pair_vectors
from robofailring.memory.references import (
    ReferenceCheck,
    absolute_reference,
    check_references,
    common_root,
    stored_resolver,
    to_stored,
)
from robofailring.outputs import check_memory_target

if TYPE_CHECKING:
    from robofailring.memory.success import SuccessMemory

# 2: entries' image references are stored relative to the manifest's absolute `data_root`.
FORMAT_VERSION: Final[int] = 2
READABLE_VERSIONS: Final[tuple[int, ...]] = (1, 2)
MANIFEST: Final[str] = "manifest.json"
INDEX: Final[str] = "index.faiss"
ENTRIES: Final[str] = "entries.jsonl"


@dataclass(frozen=True)
class MemoryEntry:
    """Grounded metadata of one memory vector (one view of one failure trajectory).

    `start` and `end` are absolute image paths in a loaded or built memory; on disk they are
    stored relative to the memory's data root (`robofailring.memory.references`).
    """

    task: str
    symbol: str
    episode: str
    view: str
    start: str
    end: str

    @property
    def description(self) -> str:
        """G(symbol), the grounded sentence."""
        return ground(self.symbol)


@dataclass(frozen=True)
class Neighbor:
    """One retrieved memory entry with its cosine similarity to the query."""

    index: int
    similarity: float
    entry: MemoryEntry

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "similarity": round(self.similarity, 6), **asdict(self.entry)}


@dataclass
class BuildStats:
    """What building a memory took in and left out (skipped views are counted and reported)."""

    trajectories: int = 0
    failures: int = 0
    ignored_non_failures: int = 0
    entries: int = 0
    skipped_views: list[dict[str, Any]] = field(default_factory=list)
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the dataset not read
    notes: list[str] = field(default_factory=list)  # said to the user after the build


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
    ) -> None:
        vectors = np.ascontiguousarray(vectors, dtype=np.float32)
        if vectors.ndim != 2 or len(vectors) != len(entries):
            raise MemoryFormatError(f"{len(entries)} entries but vectors of shape {vectors.shape}")
        self.vectors = vectors
        self.entries = list(entries)
        self.encoder = encoder
        self.dim = int(vectors.shape[1]) if vectors.size else (manifest.dim if manifest is not None else 0)
        self.manifest = manifest if manifest is not None else MemoryManifest(encoder=encoder, dim=self.dim)
        self.data_root = Path(data_root).resolve() if data_root is not None else None
        self.successes = successes  # success runs for the contrast rule (robofailring.memory.success)
        by_task: dict[str, list[int]] = {}
        for i, entry in enumerate(self.entries):
            by_task.setdefault(entry.task, []).append(i)
        self._tasks: dict[str, TaskIndex] = {}
        for task, members in by_task.items():
            ids = np.asarray(members, dtype=np.int64)
            episodes = [self.entries[i].episode for i in members]
            self._tasks[task] = TaskIndex.build(vectors[ids], ids, episodes, IndexSpec(FLAT))

    # ---------------------------------------------------------------- building
    @classmethod
    def build(
        cls,
        trajectories: Iterable[Trajectory],
        encoder: CachedEncoder,
        *,
        progress: Callable[[int], None] | None = None,
        data_root: Path | None = None,
    ) -> tuple[FailureMemory, BuildStats]:
        """Algorithm 1 over the failure trajectories; views with < 2 frames are skipped and counted.

        Symbols are validated first, so an unknown token fails the build before anything is encoded.
        Image references are kept relative to `data_root` when saved (default: the folder that
        holds all of them), so the memory resolves from any working directory.
        """
        stats = BuildStats()
        pending: list[tuple[MemoryEntry, Frame, Frame]] = []
        for trajectory in trajectories:
            stats.trajectories += 1
            if not _is_failure(trajectory):
                stats.ignored_non_failures += 1
                continue
            stats.failures += 1
            if not trajectory.symbol:
                raise SymbolError(f"failure trajectory {trajectory.key} has no failure symbol")
            try:
                parse_symbol(trajectory.symbol)
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
                )
                pending.append((entry, frames[0], frames[-1]))
        dim = encoder.dim * 2
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
        else:
            vectors = np.zeros((0, dim), dtype=np.float32)
        entries = [entry for entry, _, _ in pending]
        stats.entries = len(entries)
        manifest = MemoryManifest(
            encoder=encoder.identity,
            dim=dim,
            skipped_views=len(stats.skipped_views),
            skipped=stats.skipped_views,
            failures=stats.failures,
            ignored_non_failures=stats.ignored_non_failures,
        )
        memory = cls(vectors, entries, encoder=encoder.identity, manifest=manifest, data_root=data_root)
        return memory, stats

    # ---------------------------------------------------------------- queries
    @property
    def tasks(self) -> list[str]:
        return sorted(self._tasks)

    def __len__(self) -> int:
        return len(self.entries)

    def task_size(self, task: str) -> int:
        return self._task(task).size

    def check_encoder(self, identity: str) -> None:
        """Raise EncoderMismatchError unless `identity` is the encoder that built the memory."""
        if identity != self.encoder:
            raise EncoderMismatchError(
                f"this memory was built with encoder {self.encoder!r} but is queried with {identity!r}; "
                "rebuild the memory with the same encoder or query with the one that built it"
            )

    def _task(self, task: str) -> TaskIndex:
        found = self._tasks.get(task)
        if found is None:
            known = ", ".join(self.tasks[:20]) + (" …" if len(self.tasks) > 20 else "")
            raise UnknownTaskError(f"task {task!r} has no entry in the memory; its tasks are: {known}")
        return found

    def search(
        self, queries: np.ndarray, task: str, k: int, *, exclude_episode: str | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Top-`k` entries of `task` for each query row (eq. 5).

        Returns (similarities, global ids), both (n, k); rows are padded with NaN and -1 when the
        task has fewer than k usable entries. `exclude_episode` hides that episode's entries
        (leave-one-out). All query rows (e.g. the views of one step) go to Faiss in one call.
        """
        queries = np.ascontiguousarray(np.atleast_2d(queries), dtype=np.float32)
        if queries.shape[1] != self.dim:
            raise MemoryFormatError(f"query dimension {queries.shape[1]} != memory dimension {self.dim}")
        return self._task(task).search(queries, k, exclude_episode=exclude_episode)

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
        """
        directory = Path(directory)
        check_memory_target(directory)
        root = self.data_root or common_root(
            ref for entry in self.entries for ref in (entry.start, entry.end)
        )
        if root is not None:
            self.data_root = root
            self.manifest.data_root = str(root)
        with atomic_directory(directory) as tmp:
            index = faiss.IndexFlatIP(self.dim)
            if len(self.vectors):
                index.add(self.vectors)
            faiss.write_index(index, str(tmp / INDEX))
            with (tmp / ENTRIES).open("w", encoding="utf-8") as handle:
                for entry in self.entries:
                    stored = asdict(entry) | {
                        "start": to_stored(entry.start, root),
                        "end": to_stored(entry.end, root),
                    }
                    handle.write(json.dumps(stored) + "\n")
            if self.successes is not None:
                self.successes.write(tmp, root=root)
            (tmp / MANIFEST).write_text(
                json.dumps(self._full_manifest().to_dict(), indent=2), encoding="utf-8"
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
            successes=self.successes.manifest() if self.successes is not None else None,
            created=self.manifest.created or datetime.now(UTC).isoformat(timespec="seconds"),
        )

    def write_manifest(self, directory: Path) -> None:
        """Rewrite only the manifest of a saved memory (e.g. after calibration), atomically.

        Never while another process replaces that memory (OutputBusyError then).
        """
        with output_lock(directory):
            write_text_atomic(
                Path(directory) / MANIFEST, json.dumps(self._full_manifest().to_dict(), indent=2)
            )

    @classmethod
    def load(cls, directory: Path, *, data_root: Path | None = None) -> FailureMemory:
        """Read a saved memory; `data_root` re-roots its image references when the data moved."""
        directory = Path(directory)
        manifest_path = directory / MANIFEST
        if not manifest_path.is_file() and not restore_interrupted(directory):
            raise MemoryFormatError(f"{directory} is not a failure memory: {MANIFEST} is missing")
        try:
            manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
        except ValueError as error:  # not JSON, not UTF-8, or a number too long to read
            raise MemoryFormatError(f"{manifest_path} is not valid JSON: {error}") from error
        version = manifest.get("format_version") if isinstance(manifest, dict) else None
        if version not in READABLE_VERSIONS:
            readable = ", ".join(map(str, READABLE_VERSIONS))
            raise MemoryFormatError(
                f"{manifest_path}: format_version {version!r}, this version of robofailring reads {readable}"
            )
        manifest = MemoryManifest.parse(manifest, manifest_path)
        try:
            index = faiss.read_index(str(directory / INDEX))
        except RuntimeError as error:
            raise MemoryFormatError(f"cannot read Faiss index {directory / INDEX}: {error}") from error
        entries: list[MemoryEntry] = []
        entries_path = directory / ENTRIES
        try:
            with entries_path.open(encoding="utf-8") as handle:
                for number, line in enumerate(handle, 1):
                    if line.strip():
                        try:
                            entries.append(MemoryEntry(**parse_entry(line, entries_path, number)))
                        except TypeError as error:
                            raise MemoryFormatError(
                                f"{entries_path}:{number}: bad entry ({error})"
                            ) from error
        except (OSError, UnicodeDecodeError) as error:
            raise MemoryFormatError(f"cannot read {entries_path}: {error}") from error
        if index.ntotal != manifest.count or len(entries) != manifest.count or index.d != manifest.dim:
            raise MemoryFormatError(
                f"{directory}: manifest says {manifest.count} entries of dim {manifest.dim}, "
                f"index has {index.ntotal} of dim {index.d}, {ENTRIES} has {len(entries)}"
            )
        vectors = index.reconstruct_n(0, index.ntotal) if index.ntotal else np.zeros((0, index.d), np.float32)
        resolve, root = stored_resolver(manifest.data_root, manifest.source, data_root)
        if resolve is not None:
            entries = [
                replace(entry, start=resolve(entry.start), end=resolve(entry.end)) for entry in entries
            ]
        successes = None
        if manifest.successes:  # memories written before success contrast have none
            from robofailring.memory.success import SuccessMemory

            successes = SuccessMemory.read(directory, manifest.successes, manifest.dim, resolve=resolve)
        return cls(
            vectors,
            entries,
            encoder=manifest.encoder,
            manifest=manifest,
            data_root=root,
            successes=successes,
        )

    def check_references(self) -> ReferenceCheck:
        """Which of the entries' start/end images exist where the memory says they are."""
        return check_references(ref for entry in self.entries for ref in (entry.start, entry.end))

    # ---------------------------------------------------------------- calibration
    @property
    def calibrated_delta(self) -> float | None:
        """δ (paper rule) stored by calibration for this memory's encoder, if any."""
        return self._calibrated("delta")

    @property
    def calibrated_gamma(self) -> float | None:
        """γ (contrast rule) stored by calibration for this memory's encoder, if any."""
        return self._calibrated("gamma")

    def _calibrated(self, key: str) -> float | None:
        calibration = self.manifest.calibration
        return calibration.threshold_for(self.encoder, key) if calibration is not None else None


def _is_failure(trajectory: Trajectory) -> bool:
    if trajectory.outcome is not None:
        return trajectory.outcome is Outcome.FAILURE
    return bool(trajectory.symbol)


def encoder_spec_for(memory: FailureMemory) -> str:
    """The encoder spec that reproduces a memory's encoder identity (pixels or open_clip)."""
    return EncoderSpec.for_memory(memory.encoder, memory.manifest.encoder_spec)
