"""Triage on unlabelled simulated runs: how many failures reach the top of the ranking, and how memory grows.

Quality: the project's simulator (4 tasks, 64 px, 28 frames, three cameras) makes a pool of 27
successes and 14 failures (2 per failure family) per task, simulated once and cached. Two sets are
drawn from it, 30 episodes per task: 10 % failures (27 successes + 3 failures of 3 families) and
30 % (21 + 9). Each is triaged, unlabelled, in three ways: `nothing` (each episode against its
task's other episodes), `5 successes` (5 known-good runs per task, given as a labels file) and
`memory` (a memory of the pool's failures that are not in the set, 6 families or more per task, and
the same 5 successes per task; its default contrast rule, and the novelty rule). Measured over the
episodes not given as known: AUC, precision and recall at k (k = the number of failures), and the
share of the failures in the top 15 % of the ranking. Encoders: `pixels`, and a `trained:` encoder
trained on the memory's runs (never on the set's unknown episodes) unless --no-trained.

Scale: image episodes of 3 views x 200 frames of 16 px, their frames linked from a pool of 3000
distinct images (so that encoding, cached by content, stays cheap), triaged in a fresh process at
a few sizes with a reference of at most 10 runs per task; the peak RSS and time of each. Resuming:
10 episodes whose frames are all distinct 120x160 images, triaged from an empty embedding cache and then again
(what a run stopped half-way and started again does not encode twice), in one run, as a ratio.

    .venv/bin/python -m bench.bench_triage            # both parts
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from bench._scenes import scene
from bench._timing import print_machine
from robofailring.data.images import write_png
from robofailring.data.layouts import load_dataset
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.encoders import default_cache_dir, open_encoder
from robofailring.encoders.training import TrainEncoderConfig, train_encoder
from robofailring.memory.builder import Provenance, build_memories
from robofailring.sim import TASKS, GenerateConfig, simulate
from robofailring.triage import TriageConfig, ranking_quality, run_triage

ROOT = default_cache_dir() / "bench-triage"
KNOWN = 5  # known-good runs per task
PER_TASK = 30


def pool() -> Path:
    config = GenerateConfig(
        out=ROOT / "sim",
        tasks=TASKS,
        episodes=2,
        success_episodes=27,
        seed=0,
        image_size=64,
        frames=28,
        workers=2,
    )
    return simulate(config, label="the triage pool")


def subset(source: Path, name: str, episodes: list[dict], *, split: str | None = None) -> Path:
    """A project-layout dataset of some of the pool's episodes (folders linked, manifest rewritten;
    every episode in `split` when given)."""
    root = ROOT / "sets" / name
    root.mkdir(parents=True, exist_ok=True)
    manifest = json.loads((source / "manifest.json").read_text())
    for record in episodes:
        link = root / record["dir"]
        if not link.exists():
            link.symlink_to((source / record["dir"]).resolve(), target_is_directory=True)
    manifest["episodes"] = [r | {"split": split} for r in episodes] if split else episodes
    (root / "manifest.json").write_text(json.dumps(manifest))
    return root


def draw(source: Path, rate: float) -> tuple[Path, Path, Path, dict[str, bool], set[str]]:
    """The set at `rate` failures, its labels file of known successes, the memory's runs (all in the
    `train` split), the truth and the known successes' keys."""
    records = json.loads((source / "manifest.json").read_text())["episodes"]
    chosen, known, rest = [], [], []
    failures_per_task = round(rate * PER_TASK)
    for task in TASKS:
        successes = [r for r in records if r["task"] == task and r["outcome"] == "success"]
        failures = [r for r in records if r["task"] == task and r["outcome"] == "failure"]
        by_family: dict[str, list[dict]] = {}
        for record in failures:
            by_family.setdefault(record["kind"], []).append(record)
        spread = [
            group[i] for i in range(2) for group in by_family.values() if i < len(group)
        ]  # one per family first
        picked = spread[:failures_per_task]
        chosen += successes[: PER_TASK - failures_per_task] + picked
        known += successes[:KNOWN]
        rest += [r for r in failures if r not in picked]
    tag = f"{round(rate * 100)}pct"
    data = subset(source, f"set-{tag}", chosen)
    labels = ROOT / "sets" / f"known-{tag}.csv"
    with labels.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "outcome", "symbol"])
        writer.writerows([r["episode"], "success", ""] for r in known)
    memory_runs = subset(source, f"memory-{tag}", rest + known, split="train")
    truth = {f"{r['task']}/{r['episode']}": r["outcome"] == "failure" for r in chosen}
    return data, labels, memory_runs, truth, {f"{r['task']}/{r['episode']}" for r in known}


def memory_of(runs: Path, encoder: str, tag: str) -> Path:
    folder = ROOT / "memories" / f"{tag}-{encoder.replace(':', '_').replace('/', '_')}"
    if not (folder / "manifest.json").is_file():
        trajectories = list(load_dataset(runs))
        memory, _ = build_memories(
            trajectories, open_encoder(encoder), provenance=Provenance(data=runs, encoder=encoder)
        )
        memory.save(folder)
    return folder


def trained_encoder(runs: Path, tag: str) -> str:
    """An encoder trained on the memory's runs of one set (never on the set's unknown episodes)."""
    config = TrainEncoderConfig(data=runs, out=ROOT / f"trained-encoder-{tag}", split="train")
    return f"trained:{train_encoder(config, reuse=True)}"


def quality(encoders: list[str], trained: bool) -> list[str]:
    source = pool()
    lines = [
        "| failures | encoder | reference | rule | AUC | P@k | R@k (k = failures) | top 15 % holds | failures / episodes ranked |",
        "|---:|---|---|---|---:|---:|---:|---:|---:|",
    ]
    for rate in (0.1, 0.3):
        data, labels, memory_runs, truth, known = draw(source, rate)
        tag = f"{round(rate * 100)}pct"
        specs = [*encoders, *([trained_encoder(memory_runs, tag)] if trained else [])]
        for spec in specs:
            shown = "trained" if spec.startswith("trained:") else spec
            memory = memory_of(memory_runs, spec, tag)
            for reference, judge, extra in (
                ("nothing", DetectorConfig(encoder=spec), {}),
                (f"{KNOWN} successes/task", DetectorConfig(encoder=spec), {"labels": labels}),  # of the data
                ("memory", DetectorConfig(memory=memory), {}),
                ("memory", DetectorConfig(memory=memory, rule="novelty"), {}),
            ):
                start = time.perf_counter()
                config = TriageConfig(data=DataSelection(data, **extra), out=ROOT / "out", detector=judge)
                result = run_triage(config)
                ranked = [s for s in result.ranked if s.key not in known]
                q = ranking_quality([truth[s.key] for s in ranked])
                rule = ranked[0].rule
                lines.append(
                    f"| {round(rate * 100)} % | {shown} | {reference} | {rule} | {q.auc:.3f} | "
                    f"{q.precision_at(q.failures):.2f} | {q.recall_at(q.failures):.2f} | "
                    f"{100 * q.top_share:.0f} % | {q.failures} / {q.episodes} |"
                )
                print(lines[-1], f"({time.perf_counter() - start:.0f} s)", flush=True)
    return lines


def peer_root() -> Path | None:
    """The peer simulator's set (`bench/bench_peer.py`) when it was simulated here, else None."""
    found = sorted((default_cache_dir() / "bench-peer").glob("*/labels.csv"))
    roots = [labels.parent for labels in found if (labels.parent / "episodes").is_dir()]
    return roots[0] if roots else None


def peer(rate: float) -> list[str]:
    """Triage of the peer set's in-distribution runs, drawn to `rate` failures per task; each task
    triaged with `--task` (its episode names do not say it), the tasks ranked together by score."""
    root = peer_root()
    if root is None:
        return []
    with (root / "labels.csv").open(newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["split"] in ("train", "test")]
    tag = f"peer-{round(rate * 100)}pct"
    lines = []
    for reference in ("nothing", f"{KNOWN} successes/task"):
        scores, truth, known = [], {}, set()
        for task in sorted({r["task"] for r in rows}):
            successes = [r for r in rows if r["task"] == task and r["outcome"] == "success"]
            failures = [r for r in rows if r["task"] == task and r["outcome"] == "failure"]
            wanted = round(rate / (1 - rate) * len(successes))  # failures beside these successes
            failures = [
                failures[int(i)] for i in np.unique(np.linspace(0, len(failures) - 1, wanted).round())
            ]
            folder = ROOT / "sets" / tag / task
            folder.mkdir(parents=True, exist_ok=True)
            for r in successes + failures:
                if not (folder / r["episode"]).exists():
                    (folder / r["episode"]).symlink_to(
                        root / "episodes" / r["episode"], target_is_directory=True
                    )
                truth[f"{task}/{r['episode']}"] = r["outcome"] == "failure"
            labels = None
            if reference != "nothing":
                labels = ROOT / "sets" / f"{tag}-{task}-known.csv"
                labels.write_text(
                    "episode,outcome\n" + "".join(f"{r['episode']},success\n" for r in successes[:KNOWN])
                )
                known |= {f"{task}/{r['episode']}" for r in successes[:KNOWN]}
            result = run_triage(
                TriageConfig(data=DataSelection(folder, task=task, labels=labels), out=ROOT / "out")
            )
            scores += [s for s in result.ranked if s.key not in known]
        ranked = sorted(scores, key=lambda s: -s.rank_score if np.isfinite(s.rank_score) else np.inf)
        q = ranking_quality([truth[s.key] for s in ranked])
        lines.append(
            f"| {round(rate * 100)} % (peer) | pixels | {reference} | {ranked[0].rule} | {q.auc:.3f} | "
            f"{q.precision_at(q.failures):.2f} | {q.recall_at(q.failures):.2f} | "
            f"{100 * q.top_share:.0f} % | {q.failures} / {q.episodes} |"
        )
        print(lines[-1], flush=True)
    return lines


SCALE_SCRIPT = """
import json, sys, time
from pathlib import Path
from robofailring.triage import TriageConfig, run_triage
start = time.perf_counter()
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
result = run_triage(TriageConfig(data=DataSelection(Path(sys.argv[1]), task="pick_cube"), out=Path(sys.argv[2]),
                                 reference_runs=10, detector=DetectorConfig(placement=EncoderPlacement(cache_dir=Path(sys.argv[3])))))
status = Path("/proc/self/status").read_text()  # VmHWM: this process's own peak (ru_maxrss keeps the parent's)
peak = next(int(line.split()[1]) for line in status.splitlines() if line.startswith("VmHWM:"))
print(json.dumps({"episodes": len(result.ranked), "seconds": time.perf_counter() - start, "peak_rss_mb": peak / 1024}))
"""


def scale_data(episodes: int, *, views: int = 3, frames: int = 200, distinct: int = 3000) -> Path:
    """Episodes of 16 px frames linked from a pool of `distinct` images; `distinct` 0: every frame a
    camera-like 120x160 image of its own."""
    if distinct == 0:
        root = ROOT / "scale" / f"distinct-{episodes}"
        for episode in range(episodes):
            folder = root / f"run_{episode:05d}"
            if not folder.is_dir():
                folder.mkdir(parents=True)
                for view, t in itertools.product(range(views), range(frames)):
                    seed = (episode * views + view) * frames + t
                    write_png(folder / f"view{view}_{t}.png", scene(120, 160, seed))
        return root
    images = ROOT / "scale" / "pool"
    if not (images / f"{distinct - 1}.png").is_file():
        images.mkdir(parents=True, exist_ok=True)
        rng = np.random.default_rng(0)
        for i in range(distinct):
            write_png(images / f"{i}.png", rng.integers(0, 255, (16, 16, 3), dtype=np.uint8))
    root = ROOT / "scale" / f"runs-{episodes}"
    rng = np.random.default_rng(episodes)
    for episode in range(episodes):
        folder = root / f"run_{episode:05d}"
        if folder.is_dir():
            continue
        folder.mkdir(parents=True)
        for view in range(views):
            for t, image in enumerate(rng.integers(0, distinct, frames)):
                os.link(images / f"{image}.png", folder / f"view{view}_{t}.png")
    return root


def scale(sizes: list[int]) -> list[str]:
    lines = ["| episodes (3 views x 200 frames) | seconds | peak RSS (MB) |", "|---:|---:|---:|"]
    cache = ROOT / "scale" / "cache"
    env = {**os.environ, "ROBOFAILRING_PROGRESS": "0"}

    def run(size: int, *, distinct: int = 3000, cache: Path = cache) -> dict[str, float]:
        data = scale_data(size, distinct=distinct)
        done = subprocess.run(
            [sys.executable, "-c", SCALE_SCRIPT, str(data), str(ROOT / "scale" / "out"), str(cache)],
            check=True,
            capture_output=True,
            text=True,
            env=env,
        )
        return json.loads(done.stdout.strip().splitlines()[-1])

    cold = run(min(sizes))  # encodes the pool's 3000 images: every run after it encodes nothing new
    lines.append(f"| {min(sizes)}, cold cache | {cold['seconds']:.0f} | {cold['peak_rss_mb']:.0f} |")
    for size in sizes:
        found = run(size)
        lines.append(f"| {size} | {found['seconds']:.0f} | {found['peak_rss_mb']:.0f} |")
        print(lines[-1], flush=True)
    # resuming: 10 episodes whose 6,000 frames are all distinct (120x160), from an empty cache, then again
    fresh = ROOT / "scale" / f"cache-resume-{os.getpid()}"
    first, again = run(10, distinct=0, cache=fresh), run(10, distinct=0, cache=fresh)
    shutil.rmtree(fresh, ignore_errors=True)
    lines += [
        "",
        "| 10 episodes, every frame a distinct 120x160 image | seconds |",
        "|---|---:|",
        f"| empty cache (every frame encoded) | {first['seconds']:.1f} |",
        f"| run again (every frame from the cache) | {again['seconds']:.1f} |",
        f"| ratio | {again['seconds'] / first['seconds']:.2f} |",
    ]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--encoder", action="append", help="encoder spec (default: pixels); repeatable")
    parser.add_argument("--no-trained", action="store_true", help="skip the trained encoder")
    parser.add_argument("--sizes", default="25,50,100,200", help="episodes per scale run")
    parser.add_argument("--skip-quality", action="store_true")
    parser.add_argument("--skip-scale", action="store_true")
    parser.add_argument("--skip-peer", action="store_true", help="skip the peer simulator's set")
    args = parser.parse_args()
    print_machine()
    out = []
    if not args.skip_quality:
        out += quality(args.encoder or ["pixels"], trained=not args.no_trained)
    if not args.skip_peer:
        out += [line for rate in (0.1, 0.3) for line in peer(rate)]
    if not args.skip_scale:
        out += ["", *scale([int(s) for s in args.sizes.split(",")])]
    print("\n".join(out))


if __name__ == "__main__":
    main()
