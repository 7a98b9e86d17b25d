"""The memory's map: one 2-D map per camera view of what changed in each failure, cached beside the memory.

A memory vector is `norm([norm f(I_start) ‖ norm f(I_end)])`; its first-frame half is nearly the same
for every run of one task seen by one camera, so a map of the vectors themselves is one blob per view
(and per task) with the failure types mixed inside. Each view's map is therefore fitted on that view's
entries alone, on what changed from the first frame, `norm(norm f(I_end) − norm f(I_start))`, with the
mean change of the entry's task in that view removed (the task's typical motion): what is left is how
the failure differed, and failure types form the clusters (`bench/bench_memory_map.py` measures it).
A query `norm([f(I_0) ‖ f(I_t)])` is placed the same way in its view's map, with its task's mean.
"""

from __future__ import annotations

import hashlib
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from rfr_viz.panels.umap_layout import Map2D, fit_map_2d
from robofailring.atomic import atomic_path
from robofailring.bounded import read_npz
from robofailring.encoders.base import l2_normalize
from robofailring.errors import MemoryFormatError
from robofailring.memory.entry import MemoryEntry
from robofailring.memory.failure import FailureMemory
from robofailring.memory.pairs import CONCAT, change_of

CACHE_FILE: Final[str] = "umap.npz"
# 3: one map per view of the task-centred change (2: the fuzzy graph in numpy; 1: one map of the vectors)
CACHE_VERSION: Final[int] = 3
FEATURES: Final[str] = "change-task-centred-v1"  # what the maps are fitted on (part of the cache key)
MIN_TASK_ENTRIES: Final[int] = 2  # a task with fewer entries in a view is centred on the view's mean


@dataclass(frozen=True)
class Centres:
    """The mean change of each (view, task) of the memory, and of each view (for tasks with too few entries)."""

    by_task: Mapping[tuple[str, str], np.ndarray]
    by_view: Mapping[str, np.ndarray]

    def of(self, view: str, task: str) -> np.ndarray:
        return self.by_task.get((view, task), self.by_view[view])

    def centred(self, view: str, task: str, features: np.ndarray) -> np.ndarray:
        return l2_normalize(features - self.of(view, task))


@dataclass(frozen=True)
class MemoryMap:
    """The memory laid out per camera view (module docstring): each view's map and its entries' rows."""

    maps: Mapping[str, Map2D]  # view -> the map of its entries, views in the memory's order
    rows: Mapping[str, np.ndarray]  # view -> indices into the memory's entries, in the map's order
    centres: Centres
    digest: str  # of the memory vectors, views and tasks the maps were fitted on
    fitted: bool = False  # True when this object did the fitting (False when read from the cache)
    pairing: str = CONCAT  # how the memory's (and its queries') vectors pair frames (memory.pairs)

    @property
    def views(self) -> list[str]:
        return list(self.maps)

    @property
    def size(self) -> int:
        """Memory entries on the maps."""
        return sum(len(rows) for rows in self.rows.values())

    @property
    def method(self) -> str:
        """`umap`, `pca` (every view too small for UMAP) or `umap+pca`."""
        methods = {view_map.method for view_map in self.maps.values()} or {"umap"}
        return "umap+pca" if len(methods) > 1 else methods.pop()

    @property
    def note(self) -> str:
        """A one-line statement of how the maps were made (shown in the recording)."""
        per_view = "; ".join(f"{view}: {view_map.note}" for view, view_map in self.maps.items())
        return (
            "one map per view of what changed since the first frame, norm(f(I_end) − f(I_start)), "
            f"each task's mean change in that view removed ({per_view or 'no entries'})"
        )

    def project(self, view: str, task: str, queries: np.ndarray) -> np.ndarray | None:
        """(n, 2d) query pair vectors of one view and task -> (n, 2) coordinates in that view's map
        (None: the memory has no entry of that view)."""
        if view not in self.maps:
            return None
        features = self.centres.centred(view, task, change_of(queries, pairing=self.pairing))
        return self.maps[view].project(features)


def fit_map(memory: FailureMemory) -> MemoryMap:
    """Fit the memory's maps, one per view (UMAP, or PCA for a view below MIN_UMAP_ENTRIES entries)."""
    rows, centres, features = _view_features(memory.vectors, memory.entries, memory.pairing)
    maps = {view: fit_map_2d(features[view]) for view in rows}
    return MemoryMap(
        maps=maps,
        rows=rows,
        centres=centres,
        digest=memory_digest(memory),
        fitted=True,
        pairing=memory.pairing,
    )


def _view_features(
    vectors: np.ndarray, entries: list[MemoryEntry], pairing: str
) -> tuple[dict[str, np.ndarray], Centres, dict[str, np.ndarray]]:
    """Per view: its entries' rows, the centres, and its entries' centred change features."""
    views = np.asarray([entry.view for entry in entries], dtype=object)
    tasks = np.asarray([entry.task for entry in entries], dtype=object)
    change = change_of(vectors, pairing=pairing) if len(entries) else np.zeros((0, 1), np.float32)
    rows = {view: np.flatnonzero(views == view) for view in dict.fromkeys(views.tolist())}
    by_view = {view: change[found].mean(axis=0) for view, found in rows.items()}
    by_task = {}
    for view, found in rows.items():
        for task in dict.fromkeys(tasks[found].tolist()):
            members = found[tasks[found] == task]
            if len(members) >= MIN_TASK_ENTRIES:
                by_task[(view, task)] = change[members].mean(axis=0)
    centres = Centres(by_task=by_task, by_view=by_view)
    centred = np.empty_like(change)
    for view, found in rows.items():
        for task in dict.fromkeys(tasks[found].tolist()):
            members = found[tasks[found] == task]
            centred[members] = centres.centred(view, task, change[members])
    features = {view: centred[found] for view, found in rows.items()}
    return rows, centres, features


def memory_digest(memory: FailureMemory) -> str:
    """What the cache is keyed on: the memory vectors, each entry's view and task, and the features used."""
    data = np.ascontiguousarray(memory.vectors, dtype=np.float32)
    digest = hashlib.blake2b(data.tobytes(), digest_size=16)
    digest.update(f"{FEATURES}\0{memory.pairing}".encode())
    for entry in memory.entries:
        digest.update(f"\0{entry.view}\0{entry.task}".encode())
    return f"{data.shape[0]}x{data.shape[1] if data.ndim == 2 else 0}-{digest.hexdigest()}"


def memory_map(memory: FailureMemory, *, directory: Path | None = None) -> MemoryMap:
    """The memory's maps, read from `<directory>/umap.npz` when fitted on the same memory.

    Otherwise fitted and (with a directory) written there atomically, so the next replay does no
    UMAP work at all. A read-only memory directory only costs the caching, with a warning.
    """
    if directory is not None:
        cached = _read_cache(Path(directory) / CACHE_FILE, memory)
        if cached is not None:
            return cached
    fitted = fit_map(memory)
    if directory is not None:
        try:
            _write_cache(Path(directory) / CACHE_FILE, fitted)
        except OSError as error:
            warnings.warn(f"cannot cache the memory map in {directory}: {error}", stacklevel=2)
    return fitted


def _read_cache(path: Path, memory: FailureMemory) -> MemoryMap | None:
    if not path.is_file():
        return None
    digest = memory_digest(memory)
    try:
        data = read_npz(path, error=MemoryFormatError)  # each array's declared size checked first
        if int(data["version"]) != CACHE_VERSION or str(data["digest"]) != digest:
            return None
        rows, centres, features = _view_features(memory.vectors, memory.entries, memory.pairing)
        if [str(view) for view in data["views"]] != list(rows):
            return None
        maps = {view: _cached_map(data, position, features[view]) for position, view in enumerate(rows)}
    except (OSError, ValueError, KeyError, TypeError, MemoryFormatError):
        return None  # unreadable, crafted or older cache: refit and overwrite
    if any(view_map is None for view_map in maps.values()):
        return None
    return MemoryMap(
        maps={view: view_map for view, view_map in maps.items() if view_map is not None},
        rows=rows,
        centres=centres,
        digest=digest,
        pairing=memory.pairing,
    )


def _cached_map(data: Any, position: int, features: np.ndarray) -> Map2D | None:
    method = str(data[f"method_{position}"])
    embedding = data[f"embedding_{position}"].astype(np.float32)
    if method not in ("umap", "pca") or len(embedding) != len(features):
        return None
    has_pca = method == "pca"
    return Map2D(
        embedding=embedding,
        method="umap" if method == "umap" else "pca",
        n_neighbors=int(data[f"n_neighbors_{position}"]),
        vectors=features,
        pca_mean=data[f"pca_mean_{position}"] if has_pca else None,
        pca_components=data[f"pca_components_{position}"] if has_pca else None,
    )


def _write_cache(path: Path, fitted: MemoryMap) -> None:
    arrays: dict[str, Any] = {}
    for position, view_map in enumerate(fitted.maps.values()):
        arrays[f"method_{position}"] = np.str_(view_map.method)
        arrays[f"n_neighbors_{position}"] = np.int64(view_map.n_neighbors)
        arrays[f"embedding_{position}"] = view_map.embedding
        if view_map.pca_mean is not None and view_map.pca_components is not None:
            arrays[f"pca_mean_{position}"] = view_map.pca_mean
            arrays[f"pca_components_{position}"] = view_map.pca_components
    with atomic_path(path, suffix=".npz") as tmp, tmp.open("wb") as handle:
        np.savez(
            handle,
            version=np.int64(CACHE_VERSION),
            digest=np.str_(fitted.digest),
            views=np.asarray(fitted.views, dtype=np.str_),
            **arrays,
        )
