"""The encoder interface shared by the weight-free and the CLIP encoders."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Encoder(Protocol):
    """Maps RGB images to L2-normalised float32 embeddings.

    `identity` names the model and its weights; a memory built with one identity can only be
    queried with the same identity.
    """

    @property
    def identity(self) -> str: ...

    @property
    def dim(self) -> int: ...

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """Encode (H, W, 3) uint8 RGB images to an (N, dim) float32 array of unit rows."""
        ...


#: Why a frame embedded to nothing is not stored or scored (memories, detection).
BLANK_REASON = (
    "blank to the encoder (a dark or single-colour image, or one it returned no number for): not used"
)


def unusable(embeddings: np.ndarray) -> np.ndarray:
    """Per row, whether an embedding is no image to match: a zero row (the encoder saw a blank frame:
    black, one colour) or one with a value that is not a number."""
    rows = np.asarray(embeddings, dtype=np.float32).reshape(len(embeddings), -1)
    norms = np.linalg.norm(rows, axis=1)
    return ~np.isfinite(norms) | (norms < 0.5)


def frame_ranges(frames: Sequence[int]) -> str:
    """`4–11, 15` for frames [4, 5, …, 11, 15]: the runs of consecutive frame numbers."""
    parts: list[str] = []
    start = previous = None
    for frame in sorted(frames):
        if previous is not None and frame == previous + 1:
            previous = frame
            continue
        if start is not None:
            parts.append(f"{start}" if start == previous else f"{start}–{previous}")
        start = previous = frame
    if start is not None:
        parts.append(f"{start}" if start == previous else f"{start}–{previous}")
    return ", ".join(parts)


def l2_normalize(vectors: np.ndarray, *, axis: int = -1) -> np.ndarray:
    """Row-wise L2 normalisation in float32; zero rows stay zero."""
    vectors = np.asarray(vectors, dtype=np.float32)
    norms = np.linalg.norm(vectors, axis=axis, keepdims=True)
    return (vectors / np.maximum(norms, 1e-12)).astype(np.float32, copy=False)


def file_digest(path: Path) -> str:
    """blake2b (16 hex digits) of a file's bytes."""
    digest = hashlib.blake2b(digest_size=8)
    with Path(path).open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 22), b""):
            digest.update(block)
    return digest.hexdigest()
