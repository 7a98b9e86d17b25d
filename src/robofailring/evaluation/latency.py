"""Per-frame detection latency (paper Table 4): encoding, then retrieval, on real frames, uncached."""

from __future__ import annotations

import time

import numpy as np

from robofailring.data.model import Trajectory
from robofailring.detection.detector import FailureDetector


def measure_latency(
    detector: FailureDetector, trajectory: Trajectory, *, frames: int = 8
) -> dict[str, float]:
    """Per-frame detection latency on real frames, uncached: the median over steps of encoding all
    views, of retrieving from both memories with those embeddings, and of the two together.

    Each step is timed as its two parts, one after the other, so every step's total is its encode
    plus its retrieval and the median total is never below either median part.
    """
    views = [v for v, f in trajectory.views.items() if len(f) >= 2]
    count = min(frames, trajectory.length)
    images = [[trajectory.views[v][t].load() for v in views] for t in range(count)]
    detector.encode(images[0], views)  # warm-up (arrays are never cached)
    first: dict[str, np.ndarray] = {}
    encode_ms, retrieval_ms, total_ms = [], [], []
    for step_images in images:
        start = time.perf_counter()
        embeddings = detector.encode(step_images, views)
        encoded = time.perf_counter()
        current = {view: embedding[None] for view, embedding in zip(views, embeddings, strict=True)}
        first = first or {view: current[view][0] for view in views}
        detector.retrieve(trajectory.task, first, current)
        done = time.perf_counter()
        encode_ms.append((encoded - start) * 1000)
        retrieval_ms.append((done - encoded) * 1000)
        total_ms.append((done - start) * 1000)
    return {
        "encode": float(np.median(encode_ms)),
        "retrieval": float(np.median(retrieval_ms)),
        "total": float(np.median(total_ms)),
    }
