"""Soak (issue 24): 10,000 live steps through the step API with the Rerun sink saving to `.rrd`.

Run: .venv/bin/python -m bench.bench_soak [--steps 10000] [--image-size 32] [--entries 600] [--successes 40]

One session of a robot that runs for a long time: every step feeds three synthetic camera frames
(a smooth scene whose square moves on, so every frame is new) as live RGB arrays to
`detector.session(task, sink=LiveRecording(...))`, which logs cameras, scores, the map query, the
neighbours that changed and the nearest success frame to a file. The memory holds random unit
vectors under the `pixels` encoder's identity, failure entries and success runs pointing at real
images (so the neighbour grid and the nearest success frame have pictures), and δ = γ = 1 so the
robot is never stopped. It prints resident memory (RSS) at step 1,000 and at the end, their
difference (the growth a long session adds: the target is under 50 MiB over 10,000 steps), the peak,
and the step latency (p50, p99, max). BLAS runs single-threaded unless the environment says otherwise.
"""

# ruff: noqa: E402  (the imports follow the thread settings, which must precede numpy)
from __future__ import annotations

import os

from bench._timing import print_machine

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse
import gc
import tempfile
import time
from pathlib import Path

import numpy as np

from rfr_viz import LiveRecording, LiveTarget, fit_map
from robofailring import FailureDetector, FailureMemory, load_encoder
from robofailring.data.images import write_png
from robofailring.memory.failure import MemoryEntry
from robofailring.memory.pairs import pair_vectors
from robofailring.memory.success import SuccessMemory, SuccessRun

VIEWS = ("front", "overhead", "wrist")
TASK = "pick_cube"
MIB = 1024 * 1024


def frame(view: int, t: int, size: int) -> np.ndarray:
    """A shaded background and a square that moves on with t (no two steps alike), per view."""
    rows = np.linspace(0.5, 1.0, size, dtype=np.float32)[:, None, None]
    image = np.broadcast_to(np.array([60 + 50 * view, 110, 150], np.float32) * rows, (size, size, 3)).copy()
    side = max(size // 5, 2)
    row = (t * 3 + view * 7) % (size - side)
    col = (t * 5 // 2 + view * 11) % (size - side)
    image[row : row + side, col : col + side] = (230, 220, 40)
    return image.astype(np.uint8)


def random_unit(rng: np.random.Generator, rows: int, dim: int) -> np.ndarray:
    return pair_vectors(
        rng.standard_normal((rows, dim), np.float32),
        rng.standard_normal((rows, dim), np.float32),
        pairing="concat",
    )


def random_memory(entries: int, success_runs: int, folder: Path, size: int) -> FailureMemory:
    """`entries` random failure pair vectors, `success_runs` runs of 10 success frames; real images."""
    encoder = load_encoder("pixels")
    rng = np.random.default_rng(0)
    images = []
    for index in range(12):  # a few distinct reference images, shared round-robin
        path = folder / f"ref{index}.png"
        write_png(path, frame(index % 3, index * 9, size))
        images.append(str(path))
    listed = [
        MemoryEntry(
            task=TASK,
            symbol="grasp_wp2",
            episode=f"ep{i // 3}",
            view=VIEWS[i % 3],
            start=images[i % len(images)],
            end=images[(i + 1) % len(images)],
        )
        for i in range(entries)
    ]
    runs = [
        SuccessRun(TASK, f"ok{r}", VIEWS[r % 3], tuple(images[(r + j) % len(images)] for j in range(10)))
        for r in range(success_runs)
    ]
    successes = SuccessMemory(random_unit(rng, 10 * success_runs, encoder.dim), runs, dim=2 * encoder.dim)
    vectors = random_unit(rng, entries, encoder.dim)
    return FailureMemory(vectors, listed, encoder=encoder.identity, successes=successes)


def rss_bytes() -> int:
    """Resident set size of this process now (Linux /proc)."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--steps", type=int, default=10_000)
    parser.add_argument("--image-size", type=int, default=32)
    parser.add_argument("--entries", type=int, default=600, help="failure memory entries")
    parser.add_argument("--successes", type=int, default=40, help="success runs (10 frames each)")
    parser.add_argument(
        "--baseline", type=int, default=1_000, help="the step whose RSS growth is counted from"
    )
    args = parser.parse_args()
    print_machine()
    if args.steps <= args.baseline:
        parser.error(f"--steps must exceed --baseline ({args.baseline})")

    with tempfile.TemporaryDirectory(prefix="bench-soak-") as tmp:
        folder = Path(tmp)
        memory = random_memory(args.entries, args.successes, folder, args.image_size)
        detector = FailureDetector(memory, load_encoder("pixels"), delta=1.0, gamma=1.0, k=5)  # never fires
        target = LiveTarget(save=folder / "soak.rrd")
        latencies = np.zeros(args.steps, np.float64)
        samples: list[tuple[int, int]] = []  # (step, RSS) every 100 steps
        started = time.perf_counter()
        with LiveRecording.open(
            detector, TASK, views=VIEWS, target=target, memory_map=fit_map(memory)
        ) as live:
            session = detector.session(TASK, sink=live)
            for t in range(args.steps):
                images = {view: frame(v, t, args.image_size) for v, view in enumerate(VIEWS)}
                t0 = time.perf_counter()
                session.step(images)
                latencies[t] = time.perf_counter() - t0
                if (t + 1) % 100 == 0:
                    if t + 1 == args.baseline:
                        gc.collect()
                    samples.append((t + 1, rss_bytes()))
        gc.collect()
        total_s = time.perf_counter() - started
        size_mib = (folder / "soak.rrd").stat().st_size / MIB

    at = dict(samples)
    start, end = at[args.baseline], at[args.steps]
    peak = max(rss for _, rss in samples)
    ms = latencies * 1000
    print(
        f"soak: {args.steps} live steps, {len(VIEWS)} views of {args.image_size}px (pixels encoder), memory "
        f"{args.entries} entries + {10 * args.successes} success frames, sink: LiveRecording -> .rrd "
        f"({size_mib:.1f} MiB written), {total_s:.0f} s"
    )
    print(
        f"RSS at step {args.baseline}: {start / MIB:.1f} MiB; at step {args.steps}: {end / MIB:.1f} MiB; "
        f"growth {(end - start) / MIB:+.1f} MiB; peak {peak / MIB:.1f} MiB (sampled every 100 steps)"
    )
    print(
        f"step latency: p50 {np.percentile(ms, 50):.2f} ms, p99 {np.percentile(ms, 99):.2f} ms, "
        f"max {ms.max():.1f} ms"
    )
    trend = [f"{step}: {rss / MIB:.0f}" for step, rss in samples if step % (args.steps // 10 or 1) == 0]
    print("RSS (MiB) by step: " + ", ".join(trend))


if __name__ == "__main__":
    main()
