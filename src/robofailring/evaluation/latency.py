"""Per-frame detection latency (paper Table 4): encoding, then retrieval, on real frames, uncached."""

from __future__ import annotations

import time

import numpy as np

from robofailring.data.model import Trajectory
from robofailring.detection.detector import FailureDetector


def measure_latency(
    detector: FailureDetector, trajectory: Trajectory, *, frames: int = 8
) -> dict[str, float]:
    """Per-frame detection latency on real frames, uncached: encode all views, then retrieve."""
    views = [v for v, f in trajectory.views.items() if len(f) >= 2]
    count = min(frames, trajectory.length)
    images = [[trajectory.views[v][t].load() for v in views] for t in range(count)]
    raw = detector.encoder.encoder
    raw.encode(images[0])  # warm-up
    session = detector.session(trajectory.task)
    encode_ms, total_ms = [], []
    for step_images in images:
        start = time.perf_counter()
        raw.encode(step_images)
        encode_ms.append((time.perf_counter() - start) * 1000)
        start = time.perf_counter()
        session.step(dict(zip(views, step_images, strict=True)))
        total_ms.append((time.perf_counter() - start) * 1000)
    encode, total = float(np.median(encode_ms)), float(np.median(total_ms))
    return {"encode": encode, "retrieval": max(total - encode, 0.0), "total": total}
