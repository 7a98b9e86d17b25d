"""`pixels`: the weight-free encoder that serves the embedded default and runs anywhere.

An image is resized to a 24×24 RGB thumbnail, standardised per image (zero mean, unit
variance), and projected to 512 dimensions by a fixed Gaussian matrix drawn from a constant
seed (a Johnson–Lindenstrauss projection), then L2-normalised. The cosine of two embeddings
approximates the correlation of the two thumbnails: it sees layout and colour, not semantics.
It has the 512 dimensions of CLIP ViT-B/32, so its memory vectors have the paper's 1024, but
its similarity scale differs from CLIP's, so δ must be calibrated for it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import cv2
import numpy as np

from robofailring.encoders.base import l2_normalize

THUMBNAIL: Final[int] = 24
DIM: Final[int] = 512
_SEED: Final[int] = 20240607
IDENTITY: Final[str] = f"pixels-v1-{THUMBNAIL}px-{DIM}d"


class PixelEncoder:
    """Weight-free thumbnail-correlation encoder (see the module docstring for its limits)."""

    @property
    def identity(self) -> str:
        return IDENTITY

    @property
    def dim(self) -> int:
        return DIM

    def __init__(self) -> None:
        rng = np.random.default_rng(_SEED)
        inputs = THUMBNAIL * THUMBNAIL * 3
        self._projection = (rng.standard_normal((inputs, DIM)) / np.sqrt(DIM)).astype(np.float32)

    def _thumbnail(self, image: np.ndarray) -> np.ndarray:
        small = cv2.resize(image, (THUMBNAIL, THUMBNAIL), interpolation=cv2.INTER_AREA)
        values = small.astype(np.float32).reshape(-1)
        values -= values.mean()
        std = float(values.std())
        return values / std if std > 1e-6 else values

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if len(images) == 0:
            return np.zeros((0, DIM), dtype=np.float32)
        thumbs = np.stack([self._thumbnail(image) for image in images])
        return l2_normalize(thumbs @ self._projection)
