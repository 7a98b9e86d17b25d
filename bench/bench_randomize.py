"""Does an encoder that has seen variation detect better out of distribution, and is it more than
more frames? Three trained encoders side by side on bench_quality's cached sets (issue 21, item 3):

- `ID`: trained on an ID half's training episodes (bench_quality's `--train-encoder`);
- `ID + N random`: the same plus N simulated episodes of the same tasks under random looks
  (`train-encoder --randomize N`: colours, light, cameras and cube size drawn from wide continuous
  ranges, never near the OOD test set's fixed colours, seed 5000);
- `ID + N more ID`: the same plus N more in-distribution episodes from a seed of their own (7000,
  none of them a test episode): as many extra frames as the random ones, so a gain of `random`
  over `more ID` comes from the variation, not from the frame count.

Each is trained once per ID half (the swapped cell's encoder never saw its test frames) and judged
in bench_quality's four cells (ID, ID swapped, OOD, OOD + 2 deployment successes/task) at α; a summary
prints the contrast rule's recall, FPR and AUC per cell and encoder, the AUC gains on the same test
runs with a paired bootstrap interval (the test runs' sampling; `--seed` repeats everything with
other training seeds, the encoders' own spread), then every rule's full rows.

Run: .venv/bin/python -m bench.bench_randomize [--randomize N]... [--seed S]... [--no-control] [--alpha 0.05]
     [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bench._timing import print_machine
from bench.bench_quality import QualityRow, bench_sets, evaluate_encoder, print_rows
from robofailring.calibration.conformal import auc
from robofailring.detection.rules import CONTRAST
from robofailring.encoders import default_cache_dir
from robofailring.encoders.training import TrainEncoderConfig
from robofailring.jobs.simulate import extra_set
from robofailring.jobs.train_encoder import TrainEncoderJob, run_train_encoder, simulator_shape

CONTROL_SEED = 7000  # the extra in-distribution episodes; the bench's ID set is seed 0, OOD 1000, random 5000
CELLS = ("ID", "ID swapped", "OOD", "OOD + 2 deployment successes/task")
DRAWS = 2000  # bootstrap resamples of the test runs


def _seeds(root: Path) -> set[int]:
    return {record["seed"] for record in json.loads((root / "manifest.json").read_text())["episodes"]}


@dataclass(frozen=True)
class Arm:
    """One trained encoder of the comparison: what it sees beside an ID half, and its training seed."""

    kind: str  # "ID", "random" or "more ID"
    episodes: int = 0  # the extra episodes (random or more ID)
    seed: int = 0  # the training seed; the random episodes' seed is 5000 + it, the more ID ones' 7000 + it

    @property
    def label(self) -> str:
        extra = "" if self.kind == "ID" else f" + {self.episodes} {self.kind}"
        return f"ID{extra}" + (f" (seed {self.seed})" if self.seed else "")

    def folder(self, cache: Path, suffix: str) -> Path:
        name = {"ID": "", "random": f"-random{self.episodes}", "more ID": f"-more-id{self.episodes}"}[
            self.kind
        ]
        return cache / f"trained-encoder{name}{f'-seed{self.seed}' if self.seed else ''}{suffix}"


def _train(arm: Arm, data: Path, out: Path, *, tests: tuple[Path, Path], workers: int) -> str:
    """`arm`'s encoder on `data`'s train half, refused if an extra episode shares its seed (its object
    layout) with an episode of the test sets."""
    started = time.perf_counter()
    config = TrainEncoderConfig(data=data, out=out, seed=arm.seed)
    if arm.kind == "more ID":
        shape = simulator_shape(config)
        more = extra_set(shape, arm.episodes, look="in", seed=CONTROL_SEED + arm.seed, workers=workers)
        config = replace(config, extra_data=(more,))
    randomize = arm.episodes if arm.kind == "random" else 0
    folder = run_train_encoder(TrainEncoderJob(config, randomize=randomize, workers=workers), reuse=True)
    training = json.loads((folder / "encoder.json").read_text())["training"]
    tested = _seeds(tests[0]) | _seeds(tests[1])
    for item in training.get("extra_data", []):
        if shared := _seeds(Path(item["data"])) & tested:
            raise SystemExit(f"{item['data']} shares episode seeds with the test sets: {sorted(shared)}")
    extra = sum(item["frames"] for item in training.get("extra_data", []))
    print(
        f"{folder.name}: {training['frames']} training frames ({extra} extra), "
        f"{time.perf_counter() - started:.0f} s (0: cached; training took {training['seconds']:.0f} s)"
    )
    return f"trained:{folder}"


def _cell(row: QualityRow) -> str:
    contrast = row.result.rules.get("contrast")
    if contrast is None:
        return "—"
    recall, fpr = (("—" if math.isnan(v) else f"{100 * v:.1f}") for v in (contrast.recall, contrast.fpr))
    return f"{recall} / {fpr} / {contrast.auc:.3f}"


def print_summary(blocks: dict[Arm, list[QualityRow]], alpha: float) -> None:
    print(
        f"\nContrast rule, recall % / test FPR % / AUC (γ split-conformal at α = {alpha:g} on the memory "
        "half's successes)\n"
    )
    print("| encoder | " + " | ".join(CELLS) + " |")
    print("|---|" + "---:|" * len(CELLS))
    for arm, rows in blocks.items():
        cells = {row.protocol: _cell(row) for row in rows}
        print(f"| {arm.label} | " + " | ".join(cells.get(cell, "—") for cell in CELLS) + " |")


def _peaks(row: QualityRow) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The test runs' keys, and the contrast rule's peak score per failure and per success run, in key order."""
    scored = sorted(row.result.rule_scored(CONTRAST), key=lambda t: t.key)
    peaks = [float(t.scores().max()) for t in scored]
    failures = np.asarray([t.is_failure for t in scored])
    return [t.key for t in scored], np.asarray(peaks)[failures], np.asarray(peaks)[~failures]


def auc_gain(base: QualityRow, other: QualityRow) -> str:
    """AUC(other) − AUC(base) of the contrast rule on the same test runs, with its 95 % paired bootstrap
    interval (failure and success runs resampled separately, the same draw for both encoders)."""
    (keys_a, fail_a, ok_a), (keys_b, fail_b, ok_b) = _peaks(base), _peaks(other)
    if keys_a != keys_b:
        raise SystemExit(
            f"{base.encoder} and {other.encoder} were tested on different runs ({base.protocol})"
        )
    rng = np.random.default_rng(0)
    gains = []
    for _ in range(DRAWS):
        f = rng.integers(len(fail_a), size=len(fail_a))
        o = rng.integers(len(ok_a), size=len(ok_a))
        gains.append(auc(fail_b[f].tolist(), ok_b[o].tolist()) - auc(fail_a[f].tolist(), ok_a[o].tolist()))
    low, high = np.percentile(gains, [2.5, 97.5])
    gain = auc(fail_b.tolist(), ok_b.tolist()) - auc(fail_a.tolist(), ok_a.tolist())
    return f"{gain:+.3f} [{low:+.3f}, {high:+.3f}]"


def print_gains(blocks: dict[Arm, list[QualityRow]]) -> None:
    print("\nContrast-rule AUC gain on the same test runs, [95 % paired bootstrap interval]\n")
    print("| comparison | " + " | ".join(CELLS) + " |")
    print("|---|" + "---:|" * len(CELLS))
    pairs = []
    for arm in blocks:
        if arm.kind != "ID":
            pairs.append((Arm("ID", seed=arm.seed), arm))
        if arm.kind == "random" and Arm("more ID", arm.episodes, arm.seed) in blocks:
            pairs.append((Arm("more ID", arm.episodes, arm.seed), arm))
    for base, other in pairs:
        rows = {row.protocol: row for row in blocks[base]}, {row.protocol: row for row in blocks[other]}
        gains = [auc_gain(rows[0][cell], rows[1][cell]) for cell in CELLS]
        print(f"| {other.label} vs {base.label} | " + " | ".join(gains) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--randomize", type=int, action="append", help="extra episodes N (repeatable; default 160)"
    )
    parser.add_argument(
        "--seed", type=int, action="append", help="training seed(s) of every encoder (repeatable; default 0)"
    )
    parser.add_argument(
        "--no-control", action="store_true", help="leave out the `more ID` encoders (the frame-count control)"
    )
    parser.add_argument("--alpha", type=float, default=0.05, help="target FPR α of every rule")
    parser.add_argument("--workers", type=int, default=2, help="simulation processes")
    args = parser.parse_args()
    print_machine()
    start = time.perf_counter()
    in_dist, out_dist, swapped = bench_sets(args.workers)
    cache = default_cache_dir() / "bench-quality"
    kinds = ("random",) if args.no_control else ("random", "more ID")
    arms = [
        arm
        for seed in args.seed or [0]
        for arm in (
            Arm("ID", seed=seed),
            *(Arm(kind, n, seed) for n in args.randomize or [160] for kind in kinds),
        )
    ]
    blocks: dict[Arm, list[QualityRow]] = {}
    for arm in arms:
        halves = [
            _train(arm, data, arm.folder(cache, suffix), tests=(in_dist, out_dist), workers=args.workers)
            for data, suffix in ((in_dist, ""), (swapped, "-swapped"))
        ]
        blocks[arm] = evaluate_encoder(
            halves[0], in_dist, out_dist, alpha=args.alpha, out=cache / "runs", swapped=(swapped, halves[1])
        )
        print(f"{arm.label}: evaluated in {sum(row.seconds for row in blocks[arm]):.0f} s")
    print_summary(blocks, args.alpha)
    print_gains(blocks)
    print_rows([row for rows in blocks.values() for row in rows], args.alpha)
    print(f"\ntotal {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
