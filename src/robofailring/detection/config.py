"""The detector's settings: K neighbours per query and the scoring stride, checked where they are given."""

from __future__ import annotations

import numbers
from typing import Final

from robofailring.errors import SettingError

DEFAULT_K: Final[int] = 5
MAX_STRIDE: Final[int] = 2**63 - 1  # frame numbers are int64: a larger stride scores frame 0 alone anyway
MAX_K: Final[int] = (
    1024  # neighbours per query: each query row holds K similarities, allocated before the search
)


def _whole_number(value: object) -> bool:
    """An int (or numpy integer) that is not a bool: what Faiss and slicing take as a count."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_k(k: int) -> int:
    """K, the neighbours retrieved per query: a whole number from 1 to `MAX_K` (SettingError otherwise)."""
    if not _whole_number(k) or not 1 <= k <= MAX_K:
        raise SettingError(f"k (neighbours per query) must be a whole number from 1 to {MAX_K}, got {k}")
    return k


def check_stride(stride: int) -> int:
    """The scoring stride: a whole number from 1 to `MAX_STRIDE` (SettingError otherwise)."""
    if not _whole_number(stride) or not 1 <= stride <= MAX_STRIDE:
        raise SettingError(
            f"stride must be a whole number from 1 (every frame scored) to {MAX_STRIDE}, got {stride}"
        )
    return stride
