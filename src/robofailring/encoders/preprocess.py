"""The pixels an exported network expects, from RGB uint8 frames, exactly as its torch encoder prepares them.

An export records its preprocessing in `export.json` (`export.py`): open_clip's own transform, or a
square resize and normalisation (trained and timm encoders). `Preprocess` runs it outside the graph,
for ONNX Runtime and OpenVINO alike, and for the frames that calibrate a static int8 export.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from robofailring.encoders.trained import prepare_images
from robofailring.errors import EncoderError
from robofailring.extras import needs_extra


class Preprocess:
    """The pixels an export expects, from RGB uint8 images, exactly as the torch encoder prepares them."""

    def __init__(self, description: dict[str, Any]) -> None:
        self.kind = description.get("kind")
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
        else:
            raise EncoderError(f"unknown preprocessing {self.kind!r} in an ONNX export")

    def __call__(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if self.kind == "open_clip":
            with needs_extra("clip"):
                from PIL import Image

            return np.stack([self._transform(Image.fromarray(image)).numpy() for image in images])
        batch = prepare_images(images, self._size).transpose(0, 3, 1, 2).astype(np.float32) / np.float32(
            255.0
        )
        return np.ascontiguousarray((batch - self._mean) / self._std, dtype=np.float32)
