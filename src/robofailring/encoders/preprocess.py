"""The pixels an exported network expects, from RGB uint8 frames, exactly as its torch encoder prepares them.

An export records its preprocessing in `export.json` (`export.py`): open_clip's own transform, or a
square resize and normalisation (trained and timm encoders). `Preprocess` runs it outside the graph,
for ONNX Runtime and OpenVINO alike, and for the frames that calibrate a static int8 export.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Final

import numpy as np

from robofailring.encoders.trained import prepare_images
from robofailring.errors import EncoderError
from robofailring.extras import needs_extra

MAX_SIDE: Final[int] = 4096  # an input side no network here takes more of (224 to 448 px in practice)


def _side(value: object) -> bool:
    return type(value) is int and 1 <= value <= MAX_SIDE


def _channels(value: object) -> bool:
    return (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    )


def check_preprocess(description: object) -> dict[str, Any]:
    """An export's recorded preprocessing, checked before anything is sized by it: its kind, an input side
    (or two) from 1 to `MAX_SIDE`, three finite means and three positive spreads: a size of 100,000 (a
    1.17 TiB frame batch) is an EncoderError, never allocated (the record's digest and the model's input
    side check the rest, `export.py`, `exported.py`)."""
    if not isinstance(description, dict) or description.get("kind") not in ("open_clip", "square"):
        raise EncoderError(f"unknown preprocessing {description!r} in an ONNX export")
    size = description.get("size")
    sides = size if isinstance(size, list) and len(size) == 2 else [size]
    mean, std = description.get("mean"), description.get("std")
    if not all(_side(side) for side in sides):
        raise EncoderError(f"an ONNX export's preprocessing size must be 1 to {MAX_SIDE} px, got {size!r}")
    if not (_channels(mean) and isinstance(std, list) and _channels(std) and min(std) > 0):
        raise EncoderError(
            f"an ONNX export's preprocessing needs three means and three positive spreads, got {mean!r}, {std!r}"
        )
    return description


def preprocess_sides(description: dict[str, Any]) -> tuple[int, int]:
    """The (height, width) of the pixels a checked preprocessing makes."""
    size = description["size"]
    return (int(size[0]), int(size[1])) if isinstance(size, list) else (int(size), int(size))


class Preprocess:
    """The pixels an export expects, from RGB uint8 images, exactly as the torch encoder prepares them."""

    def __init__(self, description: dict[str, Any]) -> None:
        self.kind = check_preprocess(description)["kind"]
        self.sides = preprocess_sides(description)  # (height, width) of the pixels it makes
        if self.kind == "open_clip":
            with needs_extra("clip"):
                from open_clip.transform import PreprocessCfg, image_transform_v2

            fields = {key: value for key, value in description.items() if key != "kind"}
            fields["size"] = tuple(fields["size"]) if isinstance(fields["size"], list) else fields["size"]
            self._transform = image_transform_v2(PreprocessCfg(**fields), is_train=False)
        elif self.kind == "square":
            self._size = int(description["size"])
            self._mean = np.asarray(description["mean"], dtype=np.float32).reshape(1, 3, 1, 1)
            self._std = np.asarray(description["std"], dtype=np.float32).reshape(1, 3, 1, 1)

    def __call__(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if self.kind == "open_clip":
            with needs_extra("clip"):
                from PIL import Image

            return np.stack([self._transform(Image.fromarray(image)).numpy() for image in images])
        batch = prepare_images(images, self._size).transpose(0, 3, 1, 2).astype(np.float32) / np.float32(
            255.0
        )
        return np.ascontiguousarray((batch - self._mean) / self._std, dtype=np.float32)
