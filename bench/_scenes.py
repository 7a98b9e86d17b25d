"""Camera-like frames for the bench scripts that write image files (bench_cache.py, bench_ray.py)."""

from __future__ import annotations

import numpy as np


def scene(height: int, width: int, seed: int) -> np.ndarray:
    """A camera-like frame: smooth shading, a few objects, sensor noise (compresses like real data)."""
    rng = np.random.default_rng(seed)
    rows = np.linspace(0.5, 1.0, height, dtype=np.float32)[:, None, None]
    image = np.broadcast_to(rows * np.array([170, 160, 150], np.float32), (height, width, 3)).copy()
    for _ in range(4):
        top, left = rng.integers(0, height - height // 5), rng.integers(0, width - width // 5)
        image[top : top + height // 5, left : left + width // 5] = rng.integers(0, 255, 3)
    image += rng.normal(0, 4, image.shape)
    return image.clip(0, 255).astype(np.uint8)
