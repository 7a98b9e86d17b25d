"""Where frames are decoded and encoded: in this process (`LocalBackend`) or on a Ray cluster (`RayBackend`).

`CachedEncoder` is the one caller. It asks its backend to encode what the embedding cache lacks;
the jobs only tell it, once, which frames they will need (`CachedEncoder.prefetch`). A backend that
works `ahead` (Ray) encodes all of them in one distributed pass into the cache, so the jobs' own
loops then read every embedding back from it; the local backend encodes on demand, as the loops
ask, and does nothing ahead. Both run the same encoder (`load_encoder` of the same spec) on the
same decoded images, so a memory built either way holds the same vectors (docs/ray.md).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Protocol

import numpy as np

from robofailring.data.model import Frame
from robofailring.encoders.base import Encoder

BATCH_FRAMES = 64  # frames decoded and encoded per call of the encoder


class EncodingBackend(Protocol):
    """Encodes frames in batches; `ahead`: whether `CachedEncoder.prefetch` should hand it the frames
    a job will need before the job asks for them (a distributed pass), or leave them to be encoded
    on demand."""

    @property
    def ahead(self) -> bool: ...

    def describe(self) -> str:
        """Where it encodes, for progress bars and messages."""
        ...

    def encode_all(self, frames: Sequence[Frame]) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """(positions in `frames`, their (n, dim) float32 unit embeddings), a batch at a time, in any
        order, until every frame has been encoded once."""
        ...


class LocalBackend:
    """Decodes and encodes in this process, BATCH_FRAMES frames per call of the encoder, in order."""

    ahead = False

    def __init__(self, encoder: Encoder, *, batch_size: int = BATCH_FRAMES) -> None:
        self.encoder = encoder
        self.batch_size = batch_size

    def describe(self) -> str:
        return "this process"

    def encode_all(self, frames: Sequence[Frame]) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        for start in range(0, len(frames), self.batch_size):
            batch = frames[start : start + self.batch_size]
            vectors = self.encoder.encode([frame.load() for frame in batch])
            yield np.arange(start, start + len(batch)), np.asarray(vectors, dtype=np.float32)
