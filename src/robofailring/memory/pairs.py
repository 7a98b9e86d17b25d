"""The paper's pair vector (eq. 2–4), written once: a memory entry and a detector query alike."""

from __future__ import annotations

import numpy as np

from robofailring.encoders.base import l2_normalize


def pair_vectors(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Eq. 2–4: ``norm([norm f(I_s) ‖ norm f(I_e)])`` row-wise, for (N, d) inputs -> (N, 2d)."""
    start = l2_normalize(np.atleast_2d(start))
    end = l2_normalize(np.atleast_2d(end))
    return l2_normalize(np.concatenate([start, end], axis=1))
