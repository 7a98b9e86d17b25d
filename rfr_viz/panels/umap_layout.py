"""One 2-D map of a set of unit vectors: UMAP (cosine), or PCA below MIN_UMAP_ENTRIES, and new points placed in it.

The UMAP is umap-learn's algorithm: exact neighbours from Faiss, the fuzzy simplicial set built here in
numpy (umap-learn's numba version is compiled, uncached, in every fresh process: ~18 s before the
first map of a replay), and umap-learn's `simplicial_set_embedding` for the layout itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Final, Literal

import numpy as np

from robofailring.extras import needs_extra

if TYPE_CHECKING:
    from scipy import sparse

N_NEIGHBORS: Final[int] = 15  # umap-learn's default
MIN_DIST: Final[float] = 0.1  # umap-learn's default
MIN_UMAP_ENTRIES: Final[int] = 4  # below this the map is a PCA projection
SEED: Final[int] = 0  # the same vectors always get the same map
PROJECT_BATCH: Final[int] = 512  # queries placed per matrix product
BISECTION_STEPS: Final[int] = 64  # umap-learn's smooth_knn_dist
SMOOTH_K_TOLERANCE: Final[float] = 1e-5  # umap-learn's
MIN_K_DIST_SCALE: Final[float] = 1e-3  # umap-learn's floor on σ, relative to the mean distance

Method = Literal["umap", "pca"]


@dataclass(frozen=True)
class Map2D:
    """2-D coordinates of a set of unit vectors, and how to place new ones in the same map.

    New points (queries) are placed as UMAP's own `transform` initialises new points: the fuzzy-membership
    weighted mean of the coordinates of their `n_neighbors` nearest vectors (cosine), without
    umap's refinement epochs. A query lands among the vectors it is most similar to, and placing a
    whole trace costs one matrix product, with no UMAP model to keep. The PCA fallback is linear.
    """

    embedding: np.ndarray  # (N, 2) float32 in [-1, 1]², centred; row i = vector i
    method: Method
    n_neighbors: int  # UMAP neighbourhood size after clamping to the number of vectors
    vectors: np.ndarray  # (N, D) the vectors the map was fitted on
    pca_mean: np.ndarray | None = None  # (D,) for the PCA fallback
    pca_components: np.ndarray | None = None  # (2, D) for the PCA fallback

    @property
    def note(self) -> str:
        """How the map was made, in a few words."""
        if self.method == "umap":
            return f"UMAP (cosine, n_neighbors={self.n_neighbors}) of {len(self.embedding)} entries"
        return f"PCA of {len(self.embedding)} entries (fewer than {MIN_UMAP_ENTRIES}, too few for UMAP)"

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


def membership_weights(distances: np.ndarray) -> np.ndarray:
    """UMAP's fuzzy set memberships of each row's k neighbours (its `smooth_knn_dist`, vectorised).

    ρ is the nearest distance, σ is found by bisection so that Σ exp(-(d - ρ)/σ) = log2(k).
    """
    distances = np.asarray(distances, dtype=np.float64)
    excess = np.maximum(distances - distances.min(axis=1, keepdims=True), 0.0)
    sigma = bandwidths(excess, target=float(np.log2(max(distances.shape[1], 2))))
    sigma = np.maximum(sigma, MIN_K_DIST_SCALE * max(float(np.mean(distances)), 1e-12))
    return np.exp(-excess / sigma[:, None])


def bandwidths(excess: np.ndarray, *, target: float) -> np.ndarray:
    """σ per row, by umap-learn's bisection: Σ_j exp(-max(excess_j, 0)/σ) = target (64 steps, tolerance 1e-5)."""
    rows = len(excess)
    low, high, sigma = np.zeros(rows), np.full(rows, np.inf), np.ones(rows)
    active = np.ones(rows, dtype=bool)
    for _ in range(BISECTION_STEPS):
        total = np.exp(-np.maximum(excess, 0.0) / sigma[:, None]).sum(axis=1)
        active &= np.abs(total - target) >= SMOOTH_K_TOLERANCE
        if not active.any():
            break
        too_wide = active & (total > target)
        too_narrow = active & ~too_wide
        high = np.where(too_wide, sigma, high)
        low = np.where(too_narrow, sigma, low)
        sigma = np.where(active, np.where(np.isinf(high), sigma * 2.0, (low + high) / 2.0), sigma)
    return sigma


def fit_map_2d(vectors: np.ndarray) -> Map2D:
    """Fit the map of a set of unit vectors (UMAP, or PCA below MIN_UMAP_ENTRIES of them)."""
    vectors = np.ascontiguousarray(vectors, dtype=np.float32)
    count = len(vectors)
    if count < MIN_UMAP_ENTRIES:
        mean = vectors.mean(axis=0) if count else np.zeros(vectors.shape[1], np.float32)
        components = np.zeros((2, vectors.shape[1]), dtype=np.float32)
        if count >= 2:
            _, _, vt = np.linalg.svd(vectors - mean, full_matrices=False)
            components[: min(2, len(vt))] = vt[:2]
        components /= _extent((vectors - mean) @ components.T)
        embedding = ((vectors - mean) @ components.T).astype(np.float32)
        return Map2D(
            embedding=embedding,
            method="pca",
            n_neighbors=0,
            vectors=vectors,
            pca_mean=mean.astype(np.float32),
            pca_components=components,
        )
    n_neighbors = max(2, min(N_NEIGHBORS, count - 1))
    embedding = scaled_to_unit_box(_umap_embedding(vectors, n_neighbors))
    return Map2D(embedding=embedding, method="umap", n_neighbors=n_neighbors, vectors=vectors)


def scaled_to_unit_box(embedding: np.ndarray) -> np.ndarray:
    """A layout moved and scaled (aspect kept) so that its bounding box is centred and its longer side spans [-1, 1]."""
    centre = (embedding.max(axis=0) + embedding.min(axis=0)) / 2
    return ((embedding - centre) / _extent(embedding, centred=False)).astype(np.float32)


def _extent(points: np.ndarray, *, centred: bool = True) -> float:
    """Half the largest side of the bounding box (or the largest |coordinate|): maps land in [-1, 1]²."""
    if not len(points):
        return 1.0
    half = np.abs(points).max() if centred else float((points.max(axis=0) - points.min(axis=0)).max() / 2)
    return float(half) if half > 1e-12 else 1.0


def _umap_embedding(vectors: np.ndarray, n_neighbors: int) -> np.ndarray:
    """UMAP (cosine) of unit vectors: exact neighbours from Faiss, the fuzzy graph in numpy, umap's layout.

    The same algorithm as `umap.UMAP(metric="cosine", random_state=SEED, precomputed_knn=...).fit` with
    umap-learn's defaults (spread 1, local_connectivity 1, spectral init, 500 epochs below 10,000 points).
    """
    import faiss

    with needs_extra("viz"):  # scikit-learn comes with umap-learn
        from sklearn.utils import check_random_state
        from umap.distances import named_distances
        from umap.umap_ import find_ab_params, simplicial_set_embedding

    index = faiss.IndexFlatIP(vectors.shape[1])
    index.add(vectors)
    similarities, ids = index.search(vectors, n_neighbors)
    distances = np.clip(1.0 - similarities, 0.0, 2.0).astype(np.float32)
    a, b = find_ab_params(1.0, MIN_DIST)
    embedding, _ = simplicial_set_embedding(
        vectors,
        fuzzy_simplicial_set(ids, distances),
        2,  # n_components
        1.0,  # initial_alpha: UMAP's learning_rate
        a,
        b,
        1.0,  # gamma: UMAP's repulsion_strength
        5,  # negative_sample_rate
        None,  # n_epochs: umap's default for the graph's size
        "spectral",
        check_random_state(SEED),
        named_distances["cosine"],
        {},
        False,  # densmap
        {},
        False,  # output_dens
        tqdm_kwds={"disable": True},
    )
    return np.asarray(embedding, dtype=np.float32)


def fuzzy_simplicial_set(ids: np.ndarray, distances: np.ndarray) -> sparse.csr_matrix:
    """UMAP's fuzzy simplicial set of a k-NN graph (`umap.umap_.fuzzy_simplicial_set`, local_connectivity 1).

    `ids`/`distances` (N, k) hold each point's neighbours, nearest first, itself among them. Per point ρ
    is its nearest non-zero distance and σ solves Σ_{j≥1} exp(-(d_j - ρ)/σ) = log2(k); an edge weighs
    exp(-(d - ρ)/σ) (1 up to ρ, 0 to itself); the graph is the fuzzy union G + Gᵀ − G∘Gᵀ. Float32 where
    umap-learn's is, so the weights agree with its to the last bit or two.
    """
    with needs_extra("viz"):  # SciPy comes with umap-learn
        from scipy import sparse

    count, k = ids.shape
    distances = np.asarray(distances, dtype=np.float32)
    rho = np.where(distances > 0.0, distances, np.inf).min(axis=1)
    rho = np.where(np.isfinite(rho), rho, 0.0).astype(np.float32)
    excess = distances - rho[:, None]
    sigma = bandwidths(excess[:, 1:].astype(np.float64), target=float(np.log2(k)))
    floor = MIN_K_DIST_SCALE * np.where(rho > 0.0, distances.mean(axis=1), distances.mean())
    sigma = np.maximum(sigma, floor).astype(np.float32)
    weights = np.where(
        excess <= 0.0, 1.0, np.exp(-(np.maximum(excess, 0.0) / sigma[:, None]).astype(np.float64))
    ).astype(np.float32)
    weights[(ids == np.arange(count)[:, None]) | (ids < 0)] = 0.0
    graph = sparse.coo_matrix(
        (weights.ravel(), (np.repeat(np.arange(count), k), np.maximum(ids, 0).ravel())), shape=(count, count)
    ).tocsr()
    graph.eliminate_zeros()
    transpose = graph.transpose().tocsr()
    union = graph + transpose - graph.multiply(transpose)
    union.eliminate_zeros()
    return union.tocsr()


def knn_purity(points: np.ndarray, labels: np.ndarray, *, k: int = 5) -> float:
    """How well a map keeps labelled groups together: the mean share of each point's k nearest other
    points (Euclidean, exact) that carry its label; the chance level is Σ_c p_c²."""
    import faiss

    points = np.ascontiguousarray(points, dtype=np.float32)
    labels = np.asarray(labels)
    count = len(points)
    if count < 2:
        return float("nan")
    k = min(k, count - 1)
    index = faiss.IndexFlatL2(points.shape[1])
    index.add(points)
    _, ids = index.search(points, k + 1)
    others = np.array([[j for j in row if j != i][:k] for i, row in enumerate(ids)])
    return float((labels[others] == labels[:, None]).mean())
