"""Would progress-binned contrast thresholds help? One γ against a γ per progress bin, at the same α.

Each of B bins of normalised progress t/L gets its own split-conformal γ_b at level α/B (a union
bound keeps the run-level false-alarm rate ≤ α). Reads the in-distribution set and the `pixels`
memory that `bench/bench_quality.py` cached; prints recall, test FPR and mean T_s side by side.
Offline only: a live run does not know L, so t/L would have to come from an expected length.

Run: .venv/bin/python -m bench.bench_quality && .venv/bin/python -m bench.bench_progress_thresholds
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

from bench._timing import print_machine
from robofailring.calibration.conformal import conformal_threshold
from robofailring.data.layouts import load_dataset
from robofailring.detection.detector import FailureDetector
from robofailring.detection.rules import CONTRAST
from robofailring.encoders import CachedEncoder, default_cache_dir, encoder_slug, load_encoder
from robofailring.errors import DataError
from robofailring.memory.failure import FailureMemory
from robofailring.memory.thinning import DEFAULT_STEP

ALPHA = 0.05


def _bins(length: int, count: int) -> np.ndarray:
    return np.minimum((np.arange(length) / length * count).astype(int), count - 1)


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    print_machine()
    root = default_cache_dir() / "bench-quality"
    slug = f"{encoder_slug(load_encoder('pixels').identity)}-step{DEFAULT_STEP:g}-default"  # bench_quality's
    memory = FailureMemory.load(root / "runs" / slug / "memory")
    detector = FailureDetector(memory, CachedEncoder(load_encoder("pixels")), rule=CONTRAST)
    data = list(load_dataset(root / "sim-id").trajectories())
    calibration = [
        detector.run(t, leave_one_out=True).max_score()
        for t in data
        if t.split == "train" and not t.is_failure
    ]
    tests = [(t.is_failure, detector.run(t).max_score()) for t in data if t.split == "test"]

    def measure(thresholds: Callable[[int], np.ndarray]) -> str:
        tp = fn = fp = tn = 0
        savings = []
        for failure, scores in tests:
            fired = np.flatnonzero(scores >= thresholds(len(scores)))
            if failure:
                tp, fn = tp + bool(fired.size), fn + (not fired.size)
                if fired.size:
                    savings.append(1 - fired[0] / len(scores))
            else:
                fp, tn = fp + bool(fired.size), tn + (not fired.size)
        return (
            f"recall {100 * tp / (tp + fn):5.1f} %, test FPR {100 * fp / (fp + tn):4.1f} %, "
            f"mean T_s {100 * float(np.mean(savings)):4.1f} % ({tp + fn} failures, {fp + tn} successes)"
        )

    gamma = conformal_threshold([float(c.max()) for c in calibration], ALPHA)
    print(f"one γ = {gamma:.4f} (α = {ALPHA}): {measure(lambda length: np.full(length, gamma))}")
    for count in (2, 3, 4):
        try:
            per_bin = np.asarray(
                [
                    conformal_threshold(
                        [float(c[_bins(len(c), count) == b].max()) for c in calibration], ALPHA / count
                    )
                    for b in range(count)
                ]
            )
        except DataError as error:
            print(f"{count} bins: not possible with {len(calibration)} calibration runs ({error})")
            continue
        shown = ", ".join(f"{g:.4f}" for g in per_bin)
        print(
            f"{count} bins, γ_b = [{shown}] (α/{count} each): {measure(lambda length, g=per_bin, b=count: g[_bins(length, b)])}"
        )


if __name__ == "__main__":
    main()
