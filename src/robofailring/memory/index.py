"""Task-constrained inner-product search for the failure and success memories (paper eq. 5).

A memory is searched only within the query's task, so it keeps one Faiss index per task
(`TaskIndex`), grouped by `TaskIndexSet`. Small tasks use exact search (`flat`, `IndexFlatIP`);
a task above `APPROXIMATE_ABOVE` entries uses an inverted file of 4-bit product-quantisation
fast-scan codes whose best candidates are re-ranked on 8-bit codes of the full vectors
(`ivf_pqfs`); memories written with the earlier `ivf_sq8` still load. The kinds are in
`robofailring.memory.index_kinds`; their cost and error are measured by `bench/bench_scale.py`
(see docs/scale.md). Every search takes a batch of queries in one Faiss call, so the views of
one step share one pass. Leave-one-out hides one episode with a Faiss `IDSelector` at search time.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import faiss
import numpy as np

from robofailring.errors import MemoryFormatError, SettingError
from robofailring.memory.index_file import read_index_file
from robofailring.memory.index_kinds import (
    DEFAULT_K_FACTOR,
    FLAT,
    IVF_PQFS,
    IVF_SQ8,
    KINDS,
    IndexSpec,
    kind_of,
    pq_subquantizers,
    spec_of,
)

__all__ = ["AUTO", "FLAT", "IVF_PQFS", "IVF_SQ8", "IndexSpec", "TaskIndex", "TaskIndexSet", "choose_spec"]

AUTO: Final[str] = "auto"
# Entries of one task above which `auto` picks an approximate index. Measured (bench/bench_scale.py --crossover,
# 2-core EPYC, 32 MB L3): a flat 3-view step takes 0.38 ms at 2k entries, 2.2 ms at 5k (a task no
# longer fits the cache: 4 KB an entry), 4.9 ms at 10k; ivf_sq8 takes 0.15-0.25 ms over that range.
APPROXIMATE_ABOVE: Final[int] = 4_000
APPROXIMATE: Final[str] = IVF_PQFS  # what `auto` picks above APPROXIMATE_ABOVE
DEFAULT_NPROBE: Final[int] = 16
TRAIN_PER_LIST: Final[int] = 39  # k-means training points per list (Faiss's own lower bound)


def choose_spec(
    size: int,
    *,
    kind: str = AUTO,
    approximate_above: int = APPROXIMATE_ABOVE,
    nprobe: int | None = None,
    dim: int = 1024,
) -> IndexSpec:
    """The index for a task of `size` entries of `dim` dimensions: `flat` up to `approximate_above`
    under `auto`, `ivf_pqfs` above.

    A query of an inverted file reads the nlist float32 centroids and nprobe lists of size/nlist
    codes; nlist is chosen to balance the two (at most size // TRAIN_PER_LIST): ≈ 2·√size for
    ivf_sq8's one-byte-a-dimension codes, √(nprobe·size·code bytes / (4·dim)) for ivf_pqfs's
    half-byte PQ codes (177 at 250k entries of 1024-d, nprobe 16).
    """
    if kind == AUTO:
        kind = FLAT if size <= approximate_above else APPROXIMATE
    if kind not in KINDS:
        raise SettingError(f"index kind must be {AUTO} or one of {', '.join(KINDS)}, got {kind!r}")
    if kind == FLAT:
        return IndexSpec(FLAT)
    probes = nprobe or DEFAULT_NPROBE
    pq_m = pq_subquantizers(dim)
    balanced = 2 * math.sqrt(size) if kind == IVF_SQ8 else math.sqrt(probes * size * (pq_m / 2) / (4 * dim))
    nlist = max(1, min(round(balanced), size // TRAIN_PER_LIST))
    lists = {"nlist": nlist, "nprobe": min(probes, nlist)}
    if kind == IVF_SQ8:
        return IndexSpec(IVF_SQ8, **lists)
    return IndexSpec(kind, **lists, pq_m=pq_m, k_factor=DEFAULT_K_FACTOR)


class TaskIndex:
    """One task's entries in a Faiss inner-product index, with their global ids and episodes."""

    def __init__(self, index: faiss.Index, ids: np.ndarray, episodes: Sequence[str]) -> None:
        ids = np.asarray(ids, dtype=np.int64)
        if index.ntotal != len(ids) or len(ids) != len(episodes):
            raise MemoryFormatError(
                f"task index holds {index.ntotal} entries for {len(ids)} ids and {len(episodes)} episodes"
            )
        self.index = index
        self.spec = spec_of(index)
        self.kind = kind_of(self.spec.kind)
        self.ids = ids
        names, codes = np.unique(np.asarray(episodes, dtype=object).astype(str), return_inverse=True)
        self._episode_code = {str(name): code for code, name in enumerate(names)}
        self._codes = codes.astype(np.int32).reshape(-1)
        self._excluded: tuple[str, faiss.SearchParameters, tuple[Any, ...]] | None = None

    @classmethod
    def build(
        cls, vectors: np.ndarray, ids: np.ndarray, episodes: Sequence[str], spec: IndexSpec | None = None
    ) -> TaskIndex:
        """Index `vectors` (rows = `ids`, unit-norm float32) as `spec` says (`choose_spec` when None)."""
        vectors = np.ascontiguousarray(vectors, dtype=np.float32)
        spec = spec or choose_spec(len(vectors), dim=vectors.shape[1])
        index = kind_of(spec.kind).create(vectors.shape[1], spec)
        if kind_of(spec.kind).trained:
            if len(vectors) < spec.nlist:
                raise SettingError(
                    f"{spec.kind} with {spec.nlist} lists needs at least as many entries, got {len(vectors)}"
                )
            index.train(
                _training_sample(vectors, max(spec.nlist * TRAIN_PER_LIST, kind_of(spec.kind).min_training))
            )
        index.add(vectors)
        return cls(index, ids, episodes)

    @property
    def size(self) -> int:
        return int(self.index.ntotal)

    @property
    def nbytes(self) -> int:
        """Bytes the index holds in RAM: codes or vectors, list ids and centroids (not the Python side)."""
        return self.kind.nbytes(self.index, self.spec)

    def search(
        self, queries: np.ndarray, k: int, *, exclude_episode: str | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Top-`k` (similarities, global ids) for every query row in one Faiss call, both (n, k).

        Rows are padded with NaN and -1 when fewer than k entries are usable; `exclude_episode`
        hides that episode's entries (leave-one-out) with an IDSelector.
        """
        queries = np.ascontiguousarray(np.atleast_2d(queries), dtype=np.float32)
        similarities = np.full((len(queries), k), np.nan, dtype=np.float32)
        ids = np.full((len(queries), k), -1, dtype=np.int64)
        fetch = min(k, self.size)
        if fetch == 0 or len(queries) == 0:
            return similarities, ids
        params = self._exclusion(exclude_episode)
        raw_sims, raw_local = self.index.search(queries, fetch, params=params)
        found = raw_local >= 0
        similarities[:, :fetch] = np.where(found, raw_sims, np.nan)
        ids[:, :fetch] = np.where(found, self.ids[np.maximum(raw_local, 0)], -1)
        return similarities, ids

    def _exclusion(self, episode: str | None) -> faiss.SearchParameters | None:
        code = self._episode_code.get(episode) if episode is not None else None
        if code is None:
            return None
        if self._excluded is None or self._excluded[0] != episode:
            hidden = faiss.IDSelectorBatch(np.flatnonzero(self._codes == code).astype(np.int64))
            keep = faiss.IDSelectorNot(hidden)
            params = self.kind.search_parameters(self.index, keep)
            self._excluded = (episode or "", params, (hidden, keep))  # selectors outlive the params
        return self._excluded[1]

    def write(self, path: Path) -> None:
        faiss.write_index(self.index, str(path))

    @classmethod
    def read(
        cls,
        path: Path,
        ids: np.ndarray,
        episodes: Sequence[str],
        spec: IndexSpec | None = None,
        *,
        dim: int | None = None,
    ) -> TaskIndex:
        """Read what `write` wrote; `spec` (from the manifest) must match the file when given, and the
        file must declare `len(ids)` entries (of `dim`) and no more than it holds (`read_index_file`)."""
        index = read_index_file(path, count=len(ids), dim=dim)
        try:
            found = spec_of(index)
        except MemoryFormatError as error:
            raise MemoryFormatError(f"{path}: {error}") from error
        if spec is not None and found != spec:
            raise MemoryFormatError(
                f"{path} is a {found.to_dict()} index but the manifest says {spec.to_dict()}"
            )
        if index.ntotal != len(ids):
            raise MemoryFormatError(
                f"{path} holds {index.ntotal} entries, the memory lists {len(ids)} for it"
            )
        return cls(index, ids, episodes)


def _training_sample(vectors: np.ndarray, count: int) -> np.ndarray:
    count = min(len(vectors), count)
    if count == len(vectors):
        return vectors
    rows = np.random.default_rng(0).choice(len(vectors), size=count, replace=False)
    return vectors[np.sort(rows)]


class TaskIndexSet:
    """A memory's per-task indexes: search within one task, save and load beside the memory."""

    def __init__(self, by_task: Mapping[str, TaskIndex]) -> None:
        self.by_task = dict(by_task)

    @classmethod
    def build(
        cls,
        vectors: np.ndarray,
        tasks: Sequence[str],
        episodes: Sequence[str],
        *,
        kind: str = AUTO,
        approximate_above: int = APPROXIMATE_ABOVE,
        nprobe: int | None = None,
        progress: Callable[[int], None] | None = None,
    ) -> TaskIndexSet:
        """Index row i of `vectors` under task `tasks[i]`; its global id is i."""
        task_array = np.asarray(tasks, dtype=object)
        episode_array = np.asarray(episodes, dtype=object)
        if not len(task_array) == len(episode_array) == len(vectors):
            raise MemoryFormatError(
                f"{len(vectors)} vectors, {len(task_array)} tasks, {len(episode_array)} episodes"
            )
        by_task: dict[str, TaskIndex] = {}
        for task in sorted(set(task_array.tolist())):
            rows = np.flatnonzero(task_array == task)
            spec = choose_spec(
                len(rows), kind=kind, approximate_above=approximate_above, nprobe=nprobe, dim=vectors.shape[1]
            )
            by_task[task] = TaskIndex.build(vectors[rows], rows, episode_array[rows].tolist(), spec)
            if progress is not None:
                progress(len(rows))
        return cls(by_task)

    @property
    def tasks(self) -> list[str]:
        return sorted(self.by_task)

    def __len__(self) -> int:
        return sum(index.size for index in self.by_task.values())

    @property
    def nbytes(self) -> int:
        return sum(index.nbytes for index in self.by_task.values())

    def search(
        self, queries: np.ndarray, task: str, k: int, *, exclude_episode: str | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """`TaskIndex.search` in `task` (KeyError when the set has no such task: the memory says which)."""
        return self.by_task[task].search(queries, k, exclude_episode=exclude_episode)

    def exact_vectors(self, count: int, dim: int) -> np.ndarray | None:
        """All `count` vectors by global id, when every task's index is exact (flat); else None
        (an approximate index keeps quantised codes only)."""
        if any(index.spec.kind != FLAT for index in self.by_task.values()):
            return None
        vectors = np.zeros((count, dim), dtype=np.float32)
        for index in self.by_task.values():
            if index.size:
                vectors[index.ids] = index.index.reconstruct_n(0, index.size)
        return vectors

    def manifest(self, stem: str) -> dict[str, Any]:
        """Per task: its file, entry count, kind and parameters, for the memory's manifest."""
        return {
            task: {"file": f"{stem}.{number}.faiss", "count": index.size, **index.spec.to_dict()}
            for number, (task, index) in enumerate(sorted(self.by_task.items()))
        }

    def write(self, directory: Path, stem: str) -> dict[str, Any]:
        """Write one `<stem>.<n>.faiss` per task into `directory`; returns `manifest(stem)`."""
        section = self.manifest(stem)
        for task, described in section.items():
            self.by_task[task].write(Path(directory) / described["file"])
        return section

    @classmethod
    def read(
        cls,
        directory: Path,
        section: Mapping[str, Any],
        tasks: Sequence[str],
        episodes: Sequence[str],
        *,
        dim: int | None = None,
    ) -> TaskIndexSet:
        """Read what `write` wrote; `tasks` and `episodes` per global id, as given to `build`, the
        vectors of `dim` dimensions when given."""
        task_array = np.asarray(tasks, dtype=object)
        episode_array = np.asarray(episodes, dtype=object)
        if set(section) != set(task_array.tolist()):
            raise MemoryFormatError(
                f"{directory}: the manifest indexes tasks {sorted(section)}, the entries have {sorted(set(task_array.tolist()))}"
            )
        by_task: dict[str, TaskIndex] = {}
        for task, described in section.items():
            rows = np.flatnonzero(task_array == task)
            if described.get("count") != len(rows):
                raise MemoryFormatError(
                    f"{directory}: manifest says {described.get('count')} entries for task {task!r}, the entries have {len(rows)}"
                )
            path = Path(directory) / str(described["file"])
            by_task[task] = TaskIndex.read(
                path, rows, episode_array[rows].tolist(), IndexSpec.from_dict(described), dim=dim
            )
        return cls(by_task)
