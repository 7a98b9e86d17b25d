"""The memory map's UMAP: the fuzzy simplicial set built in numpy is umap-learn's, and the layout is UMAP's."""

from __future__ import annotations

from pathlib import Path

import faiss
import numpy as np
import pytest

from rfr_viz.panels.umap_layout import bandwidths, fuzzy_simplicial_set
from robofailring.memory.failure import FailureMemory


def _knn(vectors: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    index = faiss.IndexFlatIP(vectors.shape[1])
    index.add(vectors)
    similarities, ids = index.search(vectors, k)
    return ids, np.clip(1.0 - similarities, 0.0, 2.0).astype(np.float32)


def _unit_rows(count: int, dim: int, seed: int) -> np.ndarray:
    rows = np.random.default_rng(seed).standard_normal((count, dim)).astype(np.float32)
    return rows / np.linalg.norm(rows, axis=1, keepdims=True)


def test_bandwidths_solve_the_smooth_knn_equation() -> None:
    excess = np.array([[0.0, 0.1, 0.3, 0.7], [0.0, 0.5, 1.0, 2.0], [0.0, 1e-3, 2e-3, 4e-3]])
    sigma = bandwidths(excess, target=2.0)
    totals = np.exp(-excess / sigma[:, None]).sum(axis=1)
    np.testing.assert_allclose(totals, 2.0, atol=1e-4)
    assert sigma[2] < sigma[0] < sigma[1]  # closer neighbours, narrower kernel


def test_the_fuzzy_graph_by_hand() -> None:
    """Three points on a line, k = 3: ρ is the nearest other point, σ makes the two others weigh log2(3)."""
    ids = np.array([[0, 1, 2], [1, 0, 2], [2, 1, 0]])
    distances = np.array([[0.0, 1.0, 3.0], [0.0, 1.0, 2.0], [0.0, 2.0, 3.0]], dtype=np.float32)
    graph = fuzzy_simplicial_set(ids, distances).toarray()
    assert np.all(np.diag(graph) == 0.0) and np.allclose(graph, graph.T)
    # row 0: ρ = 1, so w(0→1) = 1 and 1 + exp(-2/σ) = log2 3; row 2: w(2→1) = 1, 1 + exp(-1/σ) = log2 3
    sigma_0 = -2.0 / np.log(np.log2(3) - 1)
    sigma_2 = -1.0 / np.log(np.log2(3) - 1)
    w02, w20 = np.exp(-2.0 / sigma_0), np.exp(-1.0 / sigma_2)
    assert graph[0, 1] == pytest.approx(1.0) and graph[1, 2] == pytest.approx(1.0)
    assert graph[0, 2] == pytest.approx(w02 + w20 - w02 * w20, rel=1e-5)


@pytest.mark.slow  # umap-learn's own graph code is compiled by numba on first use (~15 s)
def test_the_fuzzy_graph_is_umap_learns(pixels_memory_dir: Path) -> None:
    from umap.umap_ import fuzzy_simplicial_set as umap_fuzzy_simplicial_set

    for vectors in (FailureMemory.load(pixels_memory_dir).vectors, _unit_rows(400, 64, seed=3)):
        vectors = np.ascontiguousarray(vectors, dtype=np.float32)
        k = min(15, len(vectors) - 1)
        ids, distances = _knn(vectors, k)
        theirs, _, _ = umap_fuzzy_simplicial_set(
            vectors, k, np.random.RandomState(0), "precomputed", {}, ids, distances
        )
        ours = fuzzy_simplicial_set(ids, distances)
        theirs = theirs.tocsr()
        assert ours.nnz == theirs.nnz
        np.testing.assert_array_equal(ours.indptr, theirs.indptr)
        np.testing.assert_array_equal(ours.indices, theirs.indices)
        # the same float32 weights up to the last bit of a rare exp (numba's expf against numpy's)
        np.testing.assert_allclose(ours.data, theirs.data, rtol=1e-6, atol=1e-9)
