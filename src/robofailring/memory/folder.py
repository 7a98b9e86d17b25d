"""The failure memory's folder on disk: its file names and format version, the files `FailureMemory.save`
writes (index, entries, success and signal memories, vocabulary, manifest) and what `FailureMemory.load` reads
back and checks (the manifest's version, the index against its entries) before a memory is made of them."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Final

import faiss
import numpy as np

from robofailring.atomic import restore_interrupted
from robofailring.data.grounding import Vocabulary
from robofailring.errors import MemoryFormatError
from robofailring.memory.entry import MemoryEntry
from robofailring.memory.format import parse_entry, read_json, read_jsonl, stored_vocabulary
from robofailring.memory.index_file import read_index_file
from robofailring.memory.manifest import MemoryManifest, not_a_memory
from robofailring.memory.references import stored_resolver, to_stored
from robofailring.memory.signals.memory import SignalMemory

if TYPE_CHECKING:
    from robofailring.memory.success import SuccessMemory

# 2: entries' image references are stored relative to the manifest's absolute `data_root`.
FORMAT_VERSION: Final[int] = 2
READABLE_VERSIONS: Final[tuple[int, ...]] = (1, 2)
MANIFEST: Final[str] = "manifest.json"
INDEX: Final[str] = "index.faiss"
ENTRIES: Final[str] = "entries.jsonl"
VOCABULARY: Final[str] = "vocabulary.json"  # the memory's own symbols, when it has a vocabulary


@dataclass(frozen=True)
class StoredMemory:
    """What a memory folder holds, read and checked; `FailureMemory.load` makes the memory of it."""

    vectors: np.ndarray
    entries: list[MemoryEntry]  # their image references resolved
    manifest: MemoryManifest
    data_root: Path | None  # where the references were resolved from
    vocabulary: Vocabulary | None
    successes: SuccessMemory | None
    signals: SignalMemory | None


def write_memory_files(
    folder: Path,
    *,
    vectors: np.ndarray,
    dim: int,
    entries: Sequence[MemoryEntry],
    root: Path | None,
    successes: SuccessMemory | None,
    signals: SignalMemory | None,
    vocabulary: Vocabulary | None,
    manifest: MemoryManifest,
) -> None:
    """Every file of a memory into `folder` (the temporary folder `save` swaps in), its image references
    written relative to `root`."""
    index = faiss.IndexFlatIP(dim)
    if len(vectors):
        index.add(vectors)
    faiss.write_index(index, str(folder / INDEX))
    with (folder / ENTRIES).open("w", encoding="utf-8") as handle:
        for entry in entries:
            stored = entry.to_dict() | {
                "start": to_stored(entry.start, root),
                "end": to_stored(entry.end, root),
            }
            handle.write(json.dumps(stored) + "\n")
    if successes is not None:
        successes.write(folder, root=root)
    if signals is not None:
        signals.write(folder)
    if vocabulary is not None:
        (folder / VOCABULARY).write_text(json.dumps(vocabulary.to_dict(), indent=2), encoding="utf-8")
    (folder / MANIFEST).write_text(json.dumps(manifest.to_dict(), indent=2), encoding="utf-8")


def read_memory_files(directory: Path, data_root: Path | None) -> StoredMemory:
    """A memory folder's files, each checked (MemoryFormatError naming the file); `data_root` re-roots its
    image references when the data moved."""
    manifest_path = directory / MANIFEST
    if not manifest_path.exists() and not restore_interrupted(directory):
        raise not_a_memory(directory)
    manifest = read_json(manifest_path)
    version = manifest.get("format_version") if isinstance(manifest, dict) else None
    if version not in READABLE_VERSIONS:
        readable = ", ".join(map(str, READABLE_VERSIONS))
        raise MemoryFormatError(
            f"{manifest_path}: format_version {version!r}, this version of robofailring reads {readable}"
        )
    manifest = MemoryManifest.parse(manifest, manifest_path)
    vocabulary = stored_vocabulary(directory, manifest.vocabulary)
    index = read_index_file(directory / INDEX, count=manifest.count, dim=manifest.dim)
    entries = read_jsonl(
        directory / ENTRIES, lambda record: MemoryEntry(**parse_entry(record, vocabulary)), what="entry"
    )
    if index.ntotal != manifest.count or len(entries) != manifest.count or index.d != manifest.dim:
        raise MemoryFormatError(
            f"{directory}: manifest says {manifest.count} entries of dim {manifest.dim}, "
            f"index has {index.ntotal} of dim {index.d}, {ENTRIES} has {len(entries)}"
        )
    vectors = index.reconstruct_n(0, index.ntotal) if index.ntotal else np.zeros((0, index.d), np.float32)
    resolve, root = stored_resolver(manifest.data_root, manifest.source, data_root)
    if resolve is not None:
        entries = [replace(entry, start=resolve(entry.start), end=resolve(entry.end)) for entry in entries]
    successes = None
    if manifest.successes:  # memories written before success contrast have none
        from robofailring.memory.success import SuccessMemory

        successes = SuccessMemory.read(directory, manifest.successes, manifest.dim, resolve=resolve)
    signals = SignalMemory.read(directory, manifest.signals) if manifest.signals else None
    return StoredMemory(vectors, entries, manifest, root, vocabulary, successes, signals)
