"""Success-frame thinning on simulated runs (issue 14): how many frames each cosine step keeps.

Run: .venv/bin/python -m bench.bench_thinning [DATA] [--encoder pixels] [--steps 0.001,0.002,...]

DATA is a dataset of the project's layout (default: the demo's in-distribution set,
<cache>/demo-data/sim-id, written by `bash scripts/demo.sh`). For every success run and view, the
success memory's vectors u_t = norm([f_0 ‖ f_t]) are thinned (robofailring.memory.thinning.thin_run);
the table gives entries kept vs offered per step, the cosines between consecutive frames, and
what thinning does to S⁺: every success frame is queried against the other episodes' success
frames of its task (leave-one-out), with every frame kept and with the thinned memory; S⁺ can
only drop, by at most √(2·step). `--synthetic` adds the same table for bench_scale.py's 600-frame
synthetic runs (30 fps-like: consecutive frames far closer than the simulator's 40-frame runs).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bench._timing import print_machine
from robofailring import CachedEncoder, Outcome, load_dataset, load_encoder
from robofailring.encoders.cache import default_cache_dir
from robofailring.memory.pairs import pair_vectors
from robofailring.memory.thinning import thin_run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", type=Path, default=default_cache_dir() / "demo-data" / "sim-id")
    parser.add_argument("--encoder", default="pixels")
    parser.add_argument("--steps", default="0.0005,0.001,0.002,0.005,0.01,0.02")
    parser.add_argument("--cap", type=int, default=None, help="frames kept per run and view at most")
    parser.add_argument("--synthetic", action="store_true", help="also thin bench_scale.py's synthetic runs")
    args = parser.parse_args()
    print_machine()
    encoder = CachedEncoder(load_encoder(args.encoder))
    runs: list[np.ndarray] = []
    owners: list[tuple[str, str]] = []  # (task, episode) per run
    for trajectory in load_dataset(args.data):
        if trajectory.outcome is not Outcome.SUCCESS:
            continue
        for frames in trajectory.views.values():
            if len(frames) >= 2:
                embeddings = encoder.encode_frames(list(frames))
                runs.append(
                    pair_vectors(np.repeat(embeddings[:1], len(frames), axis=0), embeddings, pairing="concat")
                )
                owners.append((trajectory.task, trajectory.episode))
    if not runs:
        raise SystemExit(f"{args.data} has no success run with 2 or more frames")
    offered = sum(len(run) for run in runs)
    consecutive = np.concatenate([np.einsum("ij,ij->i", run[1:], run[:-1]) for run in runs])
    print(
        f"{args.data}: {len(runs)} success runs × views, {offered} frames offered, "
        f"{offered / len(runs):.0f} per run; encoder {args.encoder}"
    )
    print(
        "cosine of consecutive u_t: "
        + ", ".join(f"p{q} {np.percentile(consecutive, q):.5f}" for q in (5, 25, 50, 75, 95))
    )
    steps = [float(text) for text in args.steps.split(",")]
    table(runs, owners, steps, args.cap)
    if args.synthetic:
        from bench._synthetic_runs import run_vectors, task_model

        synthetic = [
            run_vectors(task_model(task), seed=run, view=0) for task in range(2) for run in range(12)
        ]
        print(f"synthetic runs (bench_scale.py): {len(synthetic)} runs of {len(synthetic[0])} frames")
        table(synthetic, [(f"t{i // 12}", f"e{i}") for i in range(len(synthetic))], steps, args.cap)


def table(runs: list[np.ndarray], owners: list[tuple[str, str]], steps: list[float], cap: int | None) -> None:
    offered = sum(len(run) for run in runs)
    print("   step | kept / offered | per run (median, min, max) | S⁺ drop: median, p99, max")
    full = _success_similarity(runs, owners, [np.arange(len(run)) for run in runs])
    for step in steps:
        kept = [thin_run(run, step=step, cap=cap).kept for run in runs]
        counts = [len(rows) for rows in kept]
        drop = full - _success_similarity(runs, owners, kept)
        print(
            f" {step:6.4f} | {sum(counts):5d} / {offered} ({sum(counts) / offered:6.1%}) | "
            f"{np.median(counts):.0f}, {min(counts)}, {max(counts)} | "
            f"{np.median(drop):.5f}, {np.percentile(drop, 99):.5f}, {drop.max():.5f}"
        )


def _success_similarity(
    runs: list[np.ndarray], owners: list[tuple[str, str]], kept: list[np.ndarray]
) -> np.ndarray:
    """S⁺ of every frame of every run against the kept frames of its task's other episodes."""
    out = []
    for run, (task, episode) in zip(runs, owners, strict=True):
        others = [
            other[rows]
            for other, rows, (other_task, other_episode) in zip(runs, kept, owners, strict=True)
            if other_task == task and other_episode != episode
        ]
        out.append((run @ np.concatenate(others).T).max(axis=1) if others else np.full(len(run), np.nan))
    return np.concatenate(out)


if __name__ == "__main__":
    main()
