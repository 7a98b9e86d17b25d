"""Probe (issue 31): the view fusions on the embedded benchmark at a small size, before/after `--fusion`.

Run: .venv/bin/python -m bench.experiments.probe_fusion_embedded [--train-encoder]

bench_quality's cells (ID, ID swapped, OOD, OOD + 2 deployment successes/task) on a smaller set than
its own (3 episodes per task and failure family, 20 successes per task in distribution; 1 and 4 out of
it), once per fusion (`max`, the default, and `per-view`), every rule at α = 0.05.
"""

from __future__ import annotations

import argparse

from bench._timing import print_machine
from bench.bench_quality import Variant, _trained, datasets, evaluate_encoder, print_rows, swapped_halves
from robofailring.encoders import default_cache_dir

SIZES = {"id_episodes": 3, "id_successes": 20, "ood_episodes": 1, "ood_successes": 4}
FUSIONS = [Variant("max", {"fusion": "max"}), Variant("per-view", {"fusion": "per-view"})]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--train-encoder", action="store_true", help="a trained encoder per half instead of pixels"
    )
    args = parser.parse_args()
    print_machine()
    in_dist, out_dist = datasets(2, **SIZES)
    swapped = swapped_halves(in_dist)
    cache = default_cache_dir() / "bench-quality"
    pair = ("pixels", "pixels")
    if args.train_encoder:
        suffix = "-".join(str(v) for v in SIZES.values())
        pair = (
            _trained(in_dist, cache / f"trained-encoder-{suffix}"),
            _trained(swapped, cache / f"trained-encoder-{suffix}-swapped"),
        )
    rows = []
    for variant in FUSIONS:
        rows += evaluate_encoder(
            pair[0],
            in_dist,
            out_dist,
            alpha=0.05,
            out=cache / "runs-fusion",
            swapped=(swapped, pair[1]),
            variant=variant,
        )
    print(f"sets: {in_dist}, {out_dist} ({SIZES})")
    print_rows(rows, 0.05)


if __name__ == "__main__":
    main()
