"""Trained encoder (issue 16): training time, encoding cost, and detection quality side by side with `pixels`.

Run: .venv/bin/python -m bench.bench_encoder [--epochs N] [--frame-stride S] [--threads T] [--reuse]

Trains `train-encoder`'s CNN on the training split of the demo-sized simulated set (simulated
once and cached, exactly as `robofailring demo` does), then, for `pixels` and the trained encoder,
builds the memory from the training failures, calibrates δ at α = 0.05 on the training successes
and evaluates with the paper's rule on the in-distribution test split and on the
out-of-distribution set. Printed per encoder and test set: the AUC of the per-trajectory peak
score (failures against successes), recall at 0 % FPR with an oracle δ, recall, FPR and mean T_s at
the calibrated δ, and the per-frame latency. Training time is wall time on this machine under
whatever load it has; the load average is printed next to it.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from sklearn.metrics import roc_auc_score

from bench._timing import median_ms, print_machine
from rfr_viz.jobs.demo import DemoConfig, simulate_datasets
from rfr_viz.panels.umap import memory_map
from robofailring import FailureMemory, load_dataset, load_encoder
from robofailring.calibration.job import CalibrateConfig, calibrate
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.grounding import failure_type
from robofailring.data.selection import DataSelection
from robofailring.encoders import default_cache_dir, encoder_slug
from robofailring.encoders.trained import CONFIG_NAME, prepare_images
from robofailring.encoders.training import TrainEncoderConfig, train_encoder
from robofailring.evaluation.job import EvaluateConfig, build_training_memory, run_evaluation
from robofailring.evaluation.metrics import rates, timeliness
from robofailring.evaluation.result import EvaluationResult
from robofailring.memory.recipe import MemoryRecipe


def demo_sets(config: DemoConfig) -> tuple[Path, Path]:
    """The demo's in- and out-of-distribution sets: the demo's own step, so the same cache."""
    return simulate_datasets(config, config.data_dir or default_cache_dir() / "demo-data")


def quality(result: EvaluationResult) -> dict[str, float]:
    """Peak-score AUC, oracle recall at 0 % FPR, and recall / FPR / mean T_s at the operating δ."""
    peaks = np.array([float(t.scores().max()) for t in result.scored])
    failure = np.array([t.is_failure for t in result.scored])
    at = rates(result.scored, result.operating_delta)
    quiet = float(peaks[~failure].max()) if (~failure).any() else -math.inf
    return {
        "auc": float(roc_auc_score(failure, peaks)) if failure.any() and (~failure).any() else math.nan,
        "oracle_recall": float(np.mean(peaks[failure] > quiet)) if failure.any() else math.nan,
        "recall": at.recall,
        "fpr": at.fpr,
        "saving": timeliness(result.scored, result.operating_delta).mean_saving,
        "latency": result.latency_ms.get("total", math.nan),
    }


def map_agreement(memory_dir: Path, neighbours: int = 5) -> dict[str, float]:
    """How the memory map clusters: the share of each entry's nearest entries in the 2-D map that
    have its failure type, its view, its task (and what a random map would give)."""
    memory = FailureMemory.load(memory_dir)
    points = memory_map(memory).embedding
    distances = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)
    np.fill_diagonal(distances, np.inf)
    nearest = np.argsort(distances, axis=1)[:, :neighbours]
    keys = {
        "type": [failure_type(e.symbol) for e in memory.entries],
        "view": [e.view for e in memory.entries],
        "task": [e.task for e in memory.entries],
    }
    shares = {}
    for name, labels in keys.items():
        values = np.array(labels)
        shares[name] = float(np.mean(values[nearest] == values[:, None]))
        _, counts = np.unique(values, return_counts=True)
        shares[f"{name}_chance"] = float(((counts / counts.sum()) ** 2).sum())
    return shares


def encoding_ms(spec: str, frames: list[np.ndarray]) -> tuple[float, float]:
    """(ms per frame in batches of 64, ms per control step of 3 views) for 64 px frames, uncached."""
    encoder = load_encoder(spec)
    encoder.encode(frames[:64])  # warm-up
    batched = median_ms(lambda: encoder.encode(frames[:64]), repeat=5) / 64
    step = median_ms(lambda: encoder.encode(frames[:3]), repeat=20)
    return batched, step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--epochs", type=int, default=TrainEncoderConfig.epochs)
    parser.add_argument("--frame-stride", type=int, default=TrainEncoderConfig.frame_stride)
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads for training")
    parser.add_argument("--target-fpr", type=float, default=0.05)
    parser.add_argument("--reuse", action="store_true", help="reuse an encoder of the same recipe and data")
    args = parser.parse_args()
    print_machine(libraries=("torch",))

    demo = DemoConfig()
    in_dist, out_dist = demo_sets(demo)
    print(f"data: {in_dist} (ID train/test), {out_dist} (OOD), {demo.image_size} px frames")
    folder = default_cache_dir() / "bench-encoder" / f"trained-e{args.epochs}-s{args.frame_stride}"
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    train_encoder(
        TrainEncoderConfig(
            data=in_dist, out=folder, epochs=args.epochs, frame_stride=args.frame_stride, threads=args.threads
        ),
        reuse=args.reuse,
        say=print,
    )
    wall = time.perf_counter() - started
    record = json.loads((folder / CONFIG_NAME).read_text())["training"]
    print(
        f"training: {record['frames']} frames of {record['trajectories']} training trajectories, "
        f"{record['recipe']['epochs']} epochs: {record['seconds']:.1f} s in the loop, {wall:.1f} s wall "
        f"with reading (this run; a reused encoder reads only), {record['threads']} torch thread(s) on "
        f"{os.cpu_count()} cores, load average {load_before:.1f} before / {os.getloadavg()[0]:.1f} after; "
        f"final training accuracy {100 * record['final_train_accuracy']:.1f} %"
    )

    specs = ("pixels", f"trained:{folder}")
    trajectory = next(t for t in load_dataset(in_dist).trajectories() if t.split == "test")
    frames = prepare_images([f.load() for frames in trajectory.views.values() for f in frames], 64)
    default_threads = torch.get_num_threads()
    for threads in sorted({1, default_threads}):
        torch.set_num_threads(threads)
        for spec in specs:
            batched, step = encoding_ms(spec, list(frames))
            print(
                f"encoding {spec} ({threads} torch thread(s)): {batched:.3f} ms per 64 px frame "
                f"(batches of 64), {step:.2f} ms per 3-view step"
            )
    torch.set_num_threads(1)  # the evaluations below: on a loaded 2-core machine one thread is far faster

    rows = []
    maps: list[tuple[str, dict[str, float]]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for spec in specs:
            slug = encoder_slug(load_encoder(spec).identity)
            base = EvaluateConfig(
                data=DataSelection(in_dist),
                recipe=MemoryRecipe(encoder=spec),
                out=Path(tmp),
                memory_out=Path(tmp) / slug,
            )
            memory, _ = build_training_memory(base)
            calibration = calibrate(
                CalibrateConfig(
                    data=base.data,
                    memory=memory,
                    threshold_policy=ThresholdPolicy(args.target_fpr),
                )
            )
            tested = {
                "ID": run_evaluation(replace(base, memory=memory, name=f"{slug}-id")),
                "OOD": run_evaluation(
                    replace(
                        base,
                        memory=memory,
                        name=f"{slug}-ood",
                        test_data=base.data.other(out_dist),
                        test_split="ood",
                    )
                ),
            }
            for name, result in tested.items():
                rows.append(
                    (slug, name, calibration.delta, result.failures, result.successes, quality(result))
                )
            maps.append((slug, map_agreement(memory)))

    print(f"\npaper rule, δ calibrated at α = {args.target_fpr} on the training successes:")
    print(
        "| encoder | test | δ | failures / successes | AUC | recall @ 0 % FPR (oracle) | recall | FPR | mean T_s | ms/frame |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for slug, name, delta, failures, successes, q in rows:
        print(
            f"| {slug} | {name} | {delta:.4f} | {failures} / {successes} | {q['auc']:.3f} | "
            f"{100 * q['oracle_recall']:.1f} % | {100 * q['recall']:.1f} % | {100 * q['fpr']:.1f} % | "
            f"{100 * q['saving']:.1f} % | {q['latency']:.2f} |"
        )

    print("\nmemory map (UMAP): share of each entry's 5 nearest map neighbours with the same … (chance)")
    for slug, shares in maps:
        print(
            f"  {slug}: failure type {100 * shares['type']:.0f} % ({100 * shares['type_chance']:.0f} %), "
            f"view {100 * shares['view']:.0f} % ({100 * shares['view_chance']:.0f} %), "
            f"task {100 * shares['task']:.0f} % ({100 * shares['task_chance']:.0f} %)"
        )


if __name__ == "__main__":
    main()
