"""What a task's signal-memory entries are (their run's episode, failure symbol and frame) and how they are laid
out for an inner-product Faiss index that ranks by Euclidean distance (`robofailring.memory.signals.memory`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Rows:
    """What each entry of one index is: its run's episode, failure symbol (None: a success) and frame."""

    episodes: np.ndarray  # str
    symbols: np.ndarray  # str, "" for a success
    frames: np.ndarray  # int


def rows_of(found: list[tuple[str, str, int]]) -> Rows:
    """`Rows` of (episode, symbol, frame) triples."""
    return Rows(
        episodes=np.asarray([e for e, _, _ in found], dtype=str),
        symbols=np.asarray([s for _, s, _ in found], dtype=str),
        frames=np.asarray([f for _, _, f in found], dtype=np.int64),
    )


def search_entries(vectors: np.ndarray) -> np.ndarray:
    """Entries for inner-product search that ranks by Euclidean distance: [y ‖ −‖y‖²/2], so a query
    [x ‖ 1] scores x·y − ‖y‖²/2 = (‖x‖² − d²)/2."""
    norms = np.einsum("ij,ij->i", vectors, vectors)[:, None]
    return np.concatenate([vectors, -0.5 * norms], axis=1).astype(np.float32)
