"""The pair vector of a first and a current frame, written once: a memory entry and a detector query alike.

`concat` is the paper's (eq. 2–4): ``norm([z_0 ‖ z_t])`` of the unit embeddings z of the first and
the current (or end) frame. Its cosine is the mean of how alike the two first frames are and how
alike the two current frames are, so a new look (lighting, colours, a moved camera) lowers both
halves for every run alike and the contrast between failure and success shrinks.

`change` keeps the first frame as context at half weight and holds the current frame as what
changed since it: ``norm([½·z_0 ‖ z_t − z_0])``. A new look shifts z_0 and z_t alike, so the
change half carries over to it (docs/memory.md, "Pairing: what changed since the first frame"). At t = 0 the
change is zero and the vector is the first frame alone.
"""

from __future__ import annotations

from typing import Final

import numpy as np

from robofailring.encoders.base import l2_normalize
from robofailring.errors import SettingError

CONCAT: Final[str] = "concat"  # the paper's pairing, eq. 2–4
CHANGE: Final[str] = "change"  # the first frame at half weight beside what changed since it
PAIRINGS: Final[tuple[str, ...]] = (CONCAT, CHANGE)
CHANGE_START_WEIGHT: Final[float] = 0.5  # the first frame's weight beside the change


def check_pairing(value: str) -> str:
    """A pairing name (`concat` or `change`); SettingError naming the choices otherwise."""
    if value not in PAIRINGS:
        raise SettingError(f"pairing must be {' or '.join(PAIRINGS)}, got {value!r}")
    return value


def pair_vectors(start: np.ndarray, end: np.ndarray, *, pairing: str) -> np.ndarray:
    """Row-wise pair vectors of (N, d) first-frame and current-frame embeddings -> (N, 2d), unit norm:
    eq. 2–4 ``norm([norm f(I_s) ‖ norm f(I_e)])`` for `concat`, ``norm([½ z_s ‖ z_e − z_s])`` for `change`."""
    start = l2_normalize(np.atleast_2d(start))
    end = l2_normalize(np.atleast_2d(end))
    if pairing == CONCAT:
        return l2_normalize(np.concatenate([start, end], axis=1))
    check_pairing(pairing)
    return l2_normalize(np.concatenate([CHANGE_START_WEIGHT * start, end - start], axis=1))


def change_of(vectors: np.ndarray, *, pairing: str) -> np.ndarray:
    """(N, 2d) pair vectors -> (N, d) unit `z_t − z_0`: what changed since the first frame (the memory map's
    feature); the zero change of a first frame stays zero."""
    vectors = np.atleast_2d(np.asarray(vectors, dtype=np.float32))
    if vectors.shape[1] % 2:
        raise ValueError(
            f"memory vectors of odd dimension {vectors.shape[1]} are not pair vectors [start ‖ end]"
        )
    half = vectors.shape[1] // 2
    check_pairing(pairing)
    change = vectors[:, half:] - vectors[:, :half] if pairing == CONCAT else vectors[:, half:]
    return l2_normalize(change)
