"""Success-frame thinning: keep a frame of a success run only if it adds something to the memory.

A run at 30 fps changes little from one frame to the next, so most of its success-memory vectors
nearly repeat the previous one. `thin_run` keeps a frame only when its cosine to the last kept
frame falls below ``1 − step``, always keeps the first and the last frame, and caps the frames
kept per run. Measured steps for the project's encoders: docs/scale.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np

from robofailring.errors import SettingError

DEFAULT_STEP: Final[float] = 0.002  # on u_t = norm([f_0 ‖ f_t]): a frame-embedding cosine step of 0.004
WINDOW: Final[int] = 64  # frames compared per numpy call while looking for the next one to keep


@dataclass(frozen=True)
class Thinned:
    """The frames of one run kept in the memory, and how many were offered."""

    kept: np.ndarray  # int64 frame indices, ascending
    offered: int

    @property
    def count(self) -> int:
        return len(self.kept)


def check_step(step: float) -> float:
    """A cosine step within [0, 2] (SettingError otherwise); 0 keeps every frame."""
    if not 0.0 <= step <= 2.0:  # also rejects NaN
        raise SettingError(f"the thinning step is a cosine distance within [0, 2], got {step}")
    return step


def thin_run(vectors: np.ndarray, *, step: float = DEFAULT_STEP, cap: int | None = None) -> Thinned:
    """Indices of the frames of one run (rows of unit-norm `vectors`, (T, D)) worth keeping.

    Greedy in time: frame t is kept when cos(v_t, v_last kept) < 1 − `step`; the first and last
    frames are always kept. When more than `cap` frames survive, `cap` of them are kept evenly
    spread over the survivors (first and last included).
    """
    check_step(step)
    if cap is not None and cap < 2:
        raise SettingError(f"the cap on frames kept per run must be at least 2 (first and last), got {cap}")
    vectors = np.asarray(vectors, dtype=np.float32)
    if vectors.ndim != 2:
        raise SettingError(f"a run's vectors must be a (frames, dim) array, got shape {vectors.shape}")
    frames = len(vectors)
    if frames <= 2 or step == 0.0:
        kept = np.arange(frames, dtype=np.int64)
    else:
        chosen = [0]
        threshold = 1.0 - step
        last, candidate = 0, 1
        while candidate < frames - 1:
            window = vectors[candidate : min(candidate + WINDOW, frames - 1)]
            below = np.flatnonzero(window @ vectors[last] < threshold)
            if below.size == 0:
                candidate += len(window)
                continue
            last = candidate + int(below[0])
            chosen.append(last)
            candidate = last + 1
        chosen.append(frames - 1)
        kept = np.asarray(chosen, dtype=np.int64)
    if cap is not None and len(kept) > cap:
        kept = kept[np.unique(np.round(np.linspace(0, len(kept) - 1, cap)).astype(np.int64))]
    return Thinned(kept=kept, offered=frames)
