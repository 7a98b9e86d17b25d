"""What a query reads and how fast this machine reads it, for bench_scale.py's bandwidth limit.

`bytes_per_query` counts what one query of a task index reads: every vector for `flat`; for the
inverted files the coarse centroids (float32), the codes of the lists Faiss's coarse quantizer
probes for that query (fast-scan lists padded to blocks of 32), and for `ivf_pqfs` the 8-bit codes of
the k_factor·k candidates it re-ranks. `memory_bandwidth` times one thread's numpy sum over an
array larger than the cache. Bytes / bandwidth is the step's limit when it only streams memory.
"""

from __future__ import annotations

import time

import faiss
import numpy as np

from robofailring.memory.index import IVF_PQFS, TaskIndex


def memory_bandwidth(gigabytes: float = 0.5) -> float:
    """Bytes per second one thread reads from RAM: the best of 5 numpy sums over an uncached array."""
    array = np.ones(int(gigabytes * 2**30) // 4, np.float32)
    best = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        array.sum()
        best = min(best, time.perf_counter() - start)
    return array.nbytes / best


def bytes_per_query(index: TaskIndex, queries: np.ndarray) -> float:
    """Mean bytes one query reads: coarse centroids + codes of the probed lists + re-ranked codes.

    Lists are the ones Faiss's coarse quantizer picks for each query; flat reads every vector.
    """
    faiss_index = index.index
    dim, kind = faiss_index.d, index.spec.kind
    if kind == "flat":
        return float(index.size * dim * 4)
    refine = 0.0
    if kind == IVF_PQFS:
        refine = faiss_index.k_factor * 1 * dim  # k = 1: k_factor SQ8 codes of `dim` bytes
        faiss_index = faiss.downcast_index(faiss_index.base_index)
    code_bytes = (index.spec.pq_m + 1) // 2 if kind == IVF_PQFS else dim
    _, lists = faiss_index.quantizer.search(np.atleast_2d(queries), faiss_index.nprobe)  # as tuned now
    sizes = np.array([faiss_index.invlists.list_size(int(i)) for i in range(faiss_index.nlist)])
    if kind == IVF_PQFS:  # fast-scan stores codes in blocks of 32
        sizes = -(-sizes // 32) * 32
    scanned = sizes[lists].sum(axis=1).mean()
    return float(faiss_index.nlist * dim * 4 + scanned * code_bytes + refine)


def limit_line(name: str, step_ms: float, step_bytes: float, bandwidth: float, failure_ms: float) -> str:
    limit = step_bytes / bandwidth * 1000
    return (
        f"{name}: reads {step_bytes / 2**20:.2f} MiB a 3-view step -> {limit:.3f} ms at {bandwidth / 1e9:.1f} GB/s; "
        f"step {step_ms:.3f} ms = {step_ms / limit:.2f}x that limit, {step_ms / failure_ms:.2f}x the failure step"
    )
