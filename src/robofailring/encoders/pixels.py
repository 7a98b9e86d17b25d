"""`pixels`: the weight-free encoder that serves the embedded default and runs anywhere.

An image is resized to a 24×24 RGB thumbnail. Two views of it are standardised (zero mean,
unit variance) and concatenated: the thumbnail itself at half weight (layout, lighting) and the
thumbnail weighted per pixel by its squared HSV saturation (coloured objects stand out from a
white robot and a plain table). The result is projected to 512 dimensions by a fixed Gaussian
matrix drawn from a constant seed (a Johnson–Lindenstrauss projection) and L2-normalised.
The cosine of two embeddings is then roughly a correlation of thumbnails that favours coloured
objects: it sees layout and colour, never semantics. It has the 512 dimensions of CLIP ViT-B/32,
so its memory vectors have the paper's 1024, but its similarity scale differs from CLIP's: δ must
be calibrated for it (`robofailring calibrate`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import cv2
import numpy as np

from robofailring.encoders.base import l2_normalize
from robofailring.encoders.spec import EncoderSpec, Network
from robofailring.errors import EncoderError

THUMBNAIL: Final[int] = 24
DIM: Final[int] = 512
LAYOUT_WEIGHT: Final[float] = 0.5
_SEED: Final[int] = 20240607
IDENTITY: Final[str] = f"pixels-v2-{THUMBNAIL}px-{DIM}d"


def _standardised(values: np.ndarray) -> np.ndarray:
    values = values.reshape(-1) - values.mean()
    std = float(values.std())
    return values / std if std > 1e-6 else values


class PixelEncoder:
    """Weight-free thumbnail encoder (see the module docstring for what it can and cannot see)."""

    @property
    def identity(self) -> str:
        return IDENTITY

    @property
    def dim(self) -> int:
        return DIM

    def __init__(self) -> None:
        rng = np.random.default_rng(_SEED)
        inputs = 2 * THUMBNAIL * THUMBNAIL * 3
        self._projection = (rng.standard_normal((inputs, DIM)) / np.sqrt(DIM)).astype(np.float32)

    def features(self, image: np.ndarray) -> np.ndarray:
        """The 2 × 24 × 24 × 3 values that are projected: layout and saturation-weighted colour."""
        small = cv2.resize(image, (THUMBNAIL, THUMBNAIL), interpolation=cv2.INTER_AREA)
        saturation = cv2.cvtColor(small, cv2.COLOR_RGB2HSV)[:, :, 1:2].astype(np.float32) / 255.0
        colour = small.astype(np.float32)
        return np.concatenate([LAYOUT_WEIGHT * _standardised(colour), _standardised(colour * saturation**2)])

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if len(images) == 0:
            return np.zeros((0, DIM), dtype=np.float32)
        return l2_normalize(np.stack([self.features(image) for image in images]) @ self._projection)


def load(spec: EncoderSpec, device: str | None) -> PixelEncoder:
    """The kind's encoder (`spec.py`): no weights, no device."""
    return PixelEncoder()


def export_identity(spec: EncoderSpec) -> tuple[str, str]:
    raise EncoderError("the pixels encoder has no network to export")


def network(spec: EncoderSpec) -> Network:
    raise EncoderError("the pixels encoder has no network to export")
