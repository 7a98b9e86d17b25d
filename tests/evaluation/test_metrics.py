"""Metrics against hand-counted cases: Recall, FPR, T_s, the sweep, and calibration."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from robofailring.evaluation.metrics import ScoredTrajectory, fine_grid, rates, sweep, timeliness


def scored(key: str, failure: bool, front: list[float], wrist: list[float] | None = None) -> ScoredTrajectory:
    similarity = {"front": np.array(front, dtype=np.float32)}
    if wrist is not None:
        similarity["wrist"] = np.array(wrist, dtype=np.float32)
    return ScoredTrajectory(
        key=key,
        task="t",
        symbol="slip_wp3" if failure else None,
        is_failure=failure,
        length=len(front),
        similarity=similarity,
    )


CASES = [
    # failures: fires at frame 2 of 10 (0.93), at 5 of 10 only in wrist (0.96), never (0.80)
    scored("f1", True, [0.5, 0.7, 0.93, 0.95] + [0.9] * 6),
    scored("f2", True, [0.6] * 10, [0.1, 0.2, 0.3, 0.4, 0.5, 0.96, 0.2, 0.2, 0.2, 0.2]),
    scored("f3", True, [0.8] * 10),
    # successes: one false alarm at 0.91, two quiet ones
    scored("s1", False, [0.2, 0.91, 0.3, 0.3]),
    scored("s2", False, [0.5, 0.6, 0.7, 0.75]),
    scored("s3", False, [0.1, 0.1, 0.1, 0.1], [0.2, 0.2, 0.2, 0.2]),
]


def test_rates_by_hand() -> None:
    at_092 = rates(CASES, 0.92)
    assert (at_092.tp, at_092.fn, at_092.fp, at_092.tn) == (2, 1, 0, 3)
    assert at_092.recall == pytest.approx(2 / 3) and at_092.fpr == 0.0
    at_090 = rates(CASES, 0.90)
    assert (at_090.tp, at_090.fn, at_090.fp, at_090.tn) == (2, 1, 1, 2)
    assert at_090.fpr == pytest.approx(1 / 3)
    at_095 = rates(CASES, 0.95)
    assert (at_095.tp, at_095.fn) == (2, 1)  # f1 reaches 0.95 at frame 3, f2's wrist 0.96
    at_097 = rates(CASES, 0.97)
    assert at_097.recall == 0.0 and at_097.fpr == 0.0


def test_the_sweep_counts_what_t_det_says_at_every_threshold() -> None:
    """The sweep judges each run by its peak once: the same counts as asking every run for its t_det at each
    δ, with NaN frames, views missing from some runs, a run of no frames, and δs equal to float32 scores."""
    rng = np.random.default_rng(7)
    runs = []
    for i in range(40):
        length = int(rng.integers(0, 12))
        front = rng.random(length).astype(np.float32)
        front[rng.random(length) < 0.2] = np.nan
        wrist = rng.random(length).astype(np.float32) if i % 3 else None
        runs.append(scored(f"r{i}", bool(i % 2), list(front), None if wrist is None else list(wrist)))
    deltas = [
        *(float(v) for run in runs for v in run.similarity["front"][:2] if np.isfinite(v)),
        0.0,
        0.5,
        1.0,
    ]
    for views in (None, ["front"], ["wrist"]):
        for delta, counted in zip(deltas, sweep(runs, deltas, views), strict=True):
            fired = {run.key: run.t_det(delta, views) is not None for run in runs}
            tp = sum(fired[run.key] for run in runs if run.is_failure)
            fp = sum(fired[run.key] for run in runs if not run.is_failure)
            assert (counted.tp, counted.fn, counted.fp, counted.tn) == (tp, 20 - tp, fp, 20 - fp), (
                delta,
                views,
            )


def test_view_ablation_by_hand() -> None:
    front_only = rates(CASES, 0.92, ["front"])
    assert (front_only.tp, front_only.fn) == (1, 2)
    wrist_only = rates(CASES, 0.92, ["wrist"])
    assert (wrist_only.tp, wrist_only.fn) == (1, 2)  # trajectories without a wrist view never fire on it


def test_timeliness_by_hand() -> None:
    at_092 = timeliness(CASES, 0.92)
    assert sorted(at_092.progress) == [0.2, 0.5]  # t_det/L = 2/10 and 5/10
    assert at_092.mean_progress == pytest.approx(0.35) and at_092.median_progress == pytest.approx(0.35)
    assert at_092.mean_saving == pytest.approx(0.65)
    counts, edges = at_092.histogram(bins=10)
    assert counts[2] == 1 and counts[5] == 1 and sum(counts) == 2 and edges[0] == 0.0 and edges[-1] == 1.0
    assert timeliness(CASES, 0.99).count == 0 and np.isnan(timeliness(CASES, 0.99).mean_progress)


def test_sweep_is_monotone_and_includes_paper_deltas() -> None:
    grid = fine_grid(CASES)
    assert {0.85, 0.9, 0.92, 0.95} <= set(grid)
    curve = sweep(CASES, grid)
    recalls, fprs = [r.recall for r in curve], [r.fpr for r in curve]
    assert all(a >= b for a, b in itertools.pairwise(recalls))
    assert all(a >= b for a, b in itertools.pairwise(fprs))
