"""thinning: which frames of a success run enter the memory."""

from __future__ import annotations

import numpy as np
import pytest

from robofailring.errors import SettingError
from robofailring.memory.thinning import thin_run


def run(frames: int, seed: int = 0, dim: int = 32) -> np.ndarray:
    """A smooth walk on the unit sphere with a pause in the middle (repeated frames)."""
    rng = np.random.default_rng(seed)
    steps = 0.03 * rng.standard_normal((frames, dim))
    steps[frames // 3 : frames // 2] = 0.0  # the robot waits: identical frames
    walk = rng.standard_normal(dim) + np.cumsum(steps, axis=0)
    return (walk / np.linalg.norm(walk, axis=1, keepdims=True)).astype(np.float32)


@pytest.mark.parametrize("step", [0.001, 0.01, 0.05])
def test_kept_frames_follow_the_step(step: float) -> None:
    vectors = run(300)
    thinned = thin_run(vectors, step=step)
    kept = thinned.kept
    assert thinned.offered == 300 and thinned.count == len(kept)
    assert kept[0] == 0 and kept[-1] == 299
    assert np.all(np.diff(kept) > 0)
    # every kept frame (but the last) moved at least `step` from the one kept before it ...
    moved = np.einsum("ij,ij->i", vectors[kept[1:-1]], vectors[kept[:-2]])
    assert np.all(moved < 1 - step)
    # ... and every dropped frame stayed within `step` of the last frame kept before it
    for frame in sorted(set(range(299)) - set(kept.tolist())):
        last = kept[kept < frame].max()
        assert float(vectors[frame] @ vectors[last]) >= 1 - step
    assert not set(range(300 // 3 + 1, 300 // 2)) & set(kept.tolist())  # the pause adds nothing


def test_a_larger_step_keeps_fewer_frames_and_zero_keeps_all() -> None:
    vectors = run(400, seed=1)
    counts = [thin_run(vectors, step=step).count for step in (0.0, 0.001, 0.01, 0.05)]
    assert counts[0] == 400
    assert counts == sorted(counts, reverse=True) and counts[-1] < counts[1]


def test_the_cap_keeps_first_last_and_spreads_the_rest() -> None:
    vectors = run(500, seed=2)
    uncapped = thin_run(vectors, step=0.001)
    assert uncapped.count > 20
    capped = thin_run(vectors, step=0.001, cap=20)
    assert capped.count == 20 and capped.offered == 500
    assert capped.kept[0] == 0 and capped.kept[-1] == 499
    assert set(capped.kept.tolist()) <= set(uncapped.kept.tolist())
    gaps = np.diff(np.searchsorted(uncapped.kept, capped.kept))
    assert gaps.max() - gaps.min() <= 1  # evenly spread over the survivors
    assert thin_run(vectors, step=0.5, cap=20).count == thin_run(vectors, step=0.5).count  # under the cap


def test_short_runs_and_bad_settings() -> None:
    assert thin_run(run(2), step=0.5).kept.tolist() == [0, 1]
    assert thin_run(run(1), step=0.5).kept.tolist() == [0]
    assert thin_run(np.repeat(run(1), 50, axis=0), step=0.01).kept.tolist() == [0, 49]
    with pytest.raises(SettingError, match="step"):
        thin_run(run(10), step=-0.1)
    with pytest.raises(SettingError, match="step"):
        thin_run(run(10), step=float("nan"))
    with pytest.raises(SettingError, match="cap"):
        thin_run(run(10), cap=1)
    with pytest.raises(SettingError, match="shape"):
        thin_run(np.zeros(10, np.float32))
