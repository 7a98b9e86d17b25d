"""Which split a trajectory is in: the dataset's own, or a deterministic hash split when it has none."""

from __future__ import annotations

import hashlib

from robofailring.data.model import Trajectory


def key_digest(trajectory: Trajectory) -> bytes:
    """A run's place in the one deterministic order of runs (the hash split, the folds, the growth curve's
    subsets): the digest of its key, the same on every machine and in every process."""
    return hashlib.blake2b(trajectory.key.encode(), digest_size=8).digest()


def _hash_split(trajectory: Trajectory, test_fraction: float) -> str:
    digest = key_digest(trajectory)
    return "test" if int.from_bytes(digest, "big") / 2**64 < test_fraction else "train"


def split_of(trajectory: Trajectory, *, has_splits: bool, test_fraction: float) -> str:
    """The trajectory's split from its dataset, or a deterministic hash split when there is none."""
    if has_splits:
        return trajectory.split or ""
    return _hash_split(trajectory, test_fraction)
