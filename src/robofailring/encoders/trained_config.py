"""A trained encoder's `encoder.json` checked before anything is allocated: a shared or edited folder is
untrusted input, and a value out of range would otherwise ask torch for terabytes or return NaNs."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Final

from robofailring.errors import EncoderError

MAX_INPUT_SIZE: Final[int] = 1024  # pixels a side: the largest the project generates or trains on
MAX_WIDTH: Final[int] = 4096  # channels of a CNN layer, and embedding dimensions
MAX_LAYERS: Final[int] = 16


def _whole(value: object, low: int, high: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and low <= value <= high


def _numbers(value: object, *, positive: bool) -> bool:
    return (
        isinstance(value, list)
        and len(value) == 3
        and all(
            isinstance(v, (int, float))
            and not isinstance(v, bool)
            and math.isfinite(v)
            and (v > 0 or not positive)
            for v in value
        )
    )


def check_trained_config(config: dict[str, Any], path: Path) -> None:
    """EncoderError naming `path` and the value when a field is out of range: the input size, the
    normalisation (three finite means, three positive finite spreads), the CNN's widths and the embedding
    width (which must be the network's own)."""
    size = config["input_size"]
    if not _whole(size, 16, MAX_INPUT_SIZE):
        raise EncoderError(
            f"{path}: input_size must be a whole number of pixels from 16 to {MAX_INPUT_SIZE}, not {size!r}"
        )
    normalize = config["normalize"]
    if not isinstance(normalize, dict) or not _numbers(normalize.get("mean"), positive=False):
        raise EncoderError(f"{path}: normalize.mean must be three finite numbers, not {normalize!r}")
    if not _numbers(normalize.get("std"), positive=True):
        raise EncoderError(
            f"{path}: normalize.std must be three positive finite numbers, not {normalize.get('std')!r}"
        )
    dim = config["embedding_dim"]
    if not _whole(dim, 1, MAX_WIDTH):
        raise EncoderError(f"{path}: embedding_dim must be a whole number from 1 to {MAX_WIDTH}, not {dim!r}")
    architecture = config["architecture"]
    if not isinstance(architecture, dict):
        raise EncoderError(f"{path}: architecture must be an object, not {architecture!r}")
    if architecture.get("kind") == "cnn":
        widths = architecture.get("widths")
        if (
            not isinstance(widths, list)
            or not 1 <= len(widths) <= MAX_LAYERS
            or not all(_whole(width, 1, MAX_WIDTH) for width in widths)
        ):
            raise EncoderError(
                f"{path}: architecture.widths must be 1 to {MAX_LAYERS} whole numbers from 1 to {MAX_WIDTH}, "
                f"not {widths!r}"
            )
        if widths[-1] != dim:
            raise EncoderError(
                f"{path}: embedding_dim {dim} is not the network's: its last layer has {widths[-1]} channels"
            )
