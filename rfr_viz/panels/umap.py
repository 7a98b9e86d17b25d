"""The memory's 2-D map: UMAP (cosine) of the memory vectors, fitted once and cached beside the memory."""

from __future__ import annotations

import hashlib
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, Literal

import numpy as np

from robofailring.atomic import atomic_path
from robofailring.extras import needs_extra
from robofailring.memory.failure import FailureMemory

CACHE_FILE: Final[str] = "umap.npz"
CACHE_VERSION: Final[int] = 1
N_NEIGHBORS: Final[int] = 15  # umap-learn's default
MIN_DIST: Final[float] = 0.1  # umap-learn's default
MIN_UMAP_ENTRIES: Final[int] = 4  # below this the map is a PCA projection
SEED: Final[int] = 0  # the same memory always gets the same map
PROJECT_BATCH: Final[int] = 512  # queries placed per matrix product

Method = Literal["umap", "pca"]


@dataclass(frozen=True)
class MemoryMap:
    """2-D coordinates of every memory entry, and how to place new queries in the same map.

    Queries are placed as UMAP's own `transform` initialises new points: the fuzzy-membership
    weighted mean of the coordinates of their `n_neighbors` nearest memory entries (cosine), without
    umap's refinement epochs. A query lands among the entries it is most similar to, and placing a
    whole trace costs one matrix product, with no UMAP model to keep. The PCA fallback is linear.
    """

    embedding: np.ndarray  # (N, 2) float32 in [-1, 1]², centred; row i = memory entry i
    method: Method
    n_neighbors: int  # UMAP neighbourhood size after clamping to the memory size
    digest: str  # of the memory vectors the map was fitted on
    vectors: np.ndarray  # (N, D) the memory vectors (not cached: they live in the memory)
    pca_mean: np.ndarray | None = None  # (D,) for the PCA fallback
    pca_components: np.ndarray | None = None  # (2, D) for the PCA fallback
    fitted: bool = False  # True when this object did the fitting (False when read from the cache)

    @property
    def note(self) -> str:
        """A one-line statement of how the map was made (shown in the recording)."""
        if self.method == "umap":
            return f"UMAP (cosine, n_neighbors={self.n_neighbors}) of {len(self.embedding)} memory entries"
        return f"PCA of {len(self.embedding)} memory entries: fewer than {MIN_UMAP_ENTRIES}, too few for UMAP"

    def project(self, queries: np.ndarray) -> np.ndarray:
        """(n, D) query vectors -> (n, 2) map coordinates, batched."""
        queries = np.ascontiguousarray(np.atleast_2d(queries), dtype=np.float32)
        if len(queries) == 0 or len(self.embedding) == 0:
            return np.zeros((len(queries), 2), dtype=np.float32)
        if self.method == "pca":
            assert self.pca_mean is not None and self.pca_components is not None
            return ((queries - self.pca_mean) @ self.pca_components.T).astype(np.float32)
        k = min(self.n_neighbors, len(self.vectors))
        placed = np.empty((len(queries), 2), dtype=np.float32)
        for start in range(0, len(queries), PROJECT_BATCH):
            distances = 1.0 - queries[start : start + PROJECT_BATCH] @ self.vectors.T
            nearest = np.argpartition(distances, k - 1, axis=1)[:, :k]
            weights = membership_weights(np.take_along_axis(distances, nearest, axis=1))
            weights /= weights.sum(axis=1, keepdims=True)
            placed[start : start + PROJECT_BATCH] = np.einsum("nk,nkc->nc", weights, self.embedding[nearest])
        return placed


def membership_weights(distances: np.ndarray, *, iterations: int = 64) -> np.ndarray:
    """UMAP's fuzzy set memberships of each row's k neighbours (its `smooth_knn_dist`, vectorised).

    ρ is the nearest distance, σ is found by bisection so that Σ exp(-(d - ρ)/σ) = log2(k).
    """
    distances = np.asarray(distances, dtype=np.float64)
    k = distances.shape[1]
    target = np.log2(max(k, 2))
    excess = np.maximum(distances - distances.min(axis=1, keepdims=True), 0.0)
    low = np.zeros(len(distances))
    high = np.full(len(distances), np.inf)
    sigma = np.ones(len(distances))
    for _ in range(iterations):
        total = np.exp(-excess / sigma[:, None]).sum(axis=1)
        too_wide = total > target
        high = np.where(too_wide, sigma, high)
        low = np.where(too_wide, low, sigma)
        sigma = np.where(np.isinf(high), sigma * 2.0, (low + high) / 2.0)
    sigma = np.maximum(sigma, 1e-3 * max(float(np.mean(distances)), 1e-12))
    return np.exp(-excess / sigma[:, None])


def vectors_digest(vectors: np.ndarray) -> str:
    """What the cache is keyed on: the memory vectors themselves."""
    data = np.ascontiguousarray(vectors, dtype=np.float32)
    return (
        f"{data.shape[0]}x{data.shape[1] if data.ndim == 2 else 0}-"
        + hashlib.blake2b(data.tobytes(), digest_size=16).hexdigest()
    )


def fit_map(vectors: np.ndarray) -> MemoryMap:
    """Fit the map of a set of unit vectors (UMAP, or PCA below MIN_UMAP_ENTRIES entries)."""
    vectors = np.ascontiguousarray(vectors, dtype=np.float32)
    digest = vectors_digest(vectors)
    count = len(vectors)
    if count < MIN_UMAP_ENTRIES:
        mean = vectors.mean(axis=0) if count else np.zeros(vectors.shape[1], np.float32)
        components = np.zeros((2, vectors.shape[1]), dtype=np.float32)
        if count >= 2:
            _, _, vt = np.linalg.svd(vectors - mean, full_matrices=False)
            components[: min(2, len(vt))] = vt[:2]
        components /= _extent((vectors - mean) @ components.T)
        embedding = ((vectors - mean) @ components.T).astype(np.float32)
        return MemoryMap(
            embedding=embedding,
            method="pca",
            n_neighbors=0,
            digest=digest,
            vectors=vectors,
            pca_mean=mean.astype(np.float32),
            pca_components=components,
            fitted=True,
        )
    n_neighbors = max(2, min(N_NEIGHBORS, count - 1))
    embedding = _umap_embedding(vectors, n_neighbors)
    embedding = (embedding - (embedding.max(axis=0) + embedding.min(axis=0)) / 2) / _extent(
        embedding, centred=False
    )
    return MemoryMap(
        embedding=embedding,
        method="umap",
        n_neighbors=n_neighbors,
        digest=digest,
        vectors=vectors,
        fitted=True,
    )


def _extent(points: np.ndarray, *, centred: bool = True) -> float:
    """Half the largest side of the bounding box (or the largest |coordinate|): maps land in [-1, 1]²."""
    if not len(points):
        return 1.0
    half = np.abs(points).max() if centred else float((points.max(axis=0) - points.min(axis=0)).max() / 2)
    return float(half) if half > 1e-12 else 1.0


def _umap_embedding(vectors: np.ndarray, n_neighbors: int) -> np.ndarray:
    """UMAP with cosine metric on exact nearest neighbours from Faiss (faster than NN-descent)."""
    import faiss

    with needs_extra("viz"):
        import umap

    index = faiss.IndexFlatIP(vectors.shape[1])
    index.add(vectors)
    similarities, ids = index.search(vectors, n_neighbors)
    distances = np.clip(1.0 - similarities, 0.0, 2.0).astype(np.float32)
    reducer = umap.UMAP(
        n_components=2,
        n_neighbors=n_neighbors,
        min_dist=MIN_DIST,
        metric="cosine",
        random_state=SEED,
        n_jobs=1,
        precomputed_knn=(ids, distances, None),
    )
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*knn_search_index.*")
        warnings.filterwarnings("ignore", message=".*n_jobs.*")
        embedding = reducer.fit_transform(vectors)
    return np.asarray(embedding, dtype=np.float32)


def memory_map(memory: FailureMemory, *, directory: Path | None = None) -> MemoryMap:
    """The map of a memory, read from `<directory>/umap.npz` when it was fitted on the same vectors.

    Otherwise fitted and (with a directory) written there atomically, so the next replay does no
    UMAP work at all. A read-only memory directory only costs the caching, with a warning.
    """
    digest = vectors_digest(memory.vectors)
    if directory is not None:
        cached = _read_cache(Path(directory) / CACHE_FILE, memory.vectors, digest)
        if cached is not None:
            return cached
    fitted = fit_map(memory.vectors)
    if directory is not None:
        try:
            _write_cache(Path(directory) / CACHE_FILE, fitted)
        except OSError as error:
            warnings.warn(f"cannot cache the memory map in {directory}: {error}", stacklevel=2)
    return fitted


def _read_cache(path: Path, vectors: np.ndarray, digest: str) -> MemoryMap | None:
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            if int(data["version"]) != CACHE_VERSION or str(data["digest"]) != digest:
                return None
            method = str(data["method"])
            if method not in ("umap", "pca"):
                return None
            has_pca = method == "pca"
            return MemoryMap(
                embedding=data["embedding"].astype(np.float32),
                method="umap" if method == "umap" else "pca",
                n_neighbors=int(data["n_neighbors"]),
                digest=digest,
                vectors=np.ascontiguousarray(vectors, dtype=np.float32),
                pca_mean=data["pca_mean"] if has_pca else None,
                pca_components=data["pca_components"] if has_pca else None,
            )
    except (OSError, ValueError, KeyError):
        return None  # unreadable or older cache: refit and overwrite


def _write_cache(path: Path, fitted: MemoryMap) -> None:
    extra: dict[str, Any] = {}
    if fitted.pca_mean is not None and fitted.pca_components is not None:
        extra = {"pca_mean": fitted.pca_mean, "pca_components": fitted.pca_components}
    with atomic_path(path, suffix=".npz") as tmp, tmp.open("wb") as handle:
        np.savez(
            handle,
            version=np.int64(CACHE_VERSION),
            digest=np.str_(fitted.digest),
            method=np.str_(fitted.method),
            n_neighbors=np.int64(fitted.n_neighbors),
            embedding=fitted.embedding,
            **extra,
        )
