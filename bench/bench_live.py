"""Live view cost (issue 12): latency a step of the step API gains from the Rerun sink, 3 views; and
(issue 50) what a step of the robot's signals costs at step 10 and at step 40,000 of one session.

Run: .venv/bin/python -m bench.bench_live [--steps 200] [--image-size 128] [--entries 1500] [--connect URL]
     [--signal-steps 40000] [--signals-only]

The frames are the simulated robot's own (three cameras), fed as live RGB arrays; the memory holds
random unit vectors under the `pixels` encoder's identity whose entries point at real images (so the
neighbour grid has pictures to log). The same frames go through a session without a sink and through
one with `rfr_viz.LiveRecording` writing to a file (and to a viewer with --connect), interleaved
step by step; the table prints per-step latency of both side by side and the difference.
With random vectors the K neighbours change at every step, so the sink logs all 3 × K start/end
images every step: the worst case (in a real run they change at a few frames only).
BLAS runs single-threaded (as set below, unless the environment says otherwise): on a busy
2-core machine its threads only add contention to a per-step latency measurement.
"""

# ruff: noqa: E402  (the imports follow the thread settings, which must precede numpy)
from __future__ import annotations

import os

from bench._timing import print_machine

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse
import resource
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from rfr_viz import LiveRecording, LiveTarget, fit_map
from robofailring import FailureDetector, FailureMemory, load_encoder
from robofailring.data.images import write_png
from robofailring.detection.signal_scores import SignalHistory
from robofailring.memory.failure import MemoryEntry
from robofailring.memory.pairs import pair_vectors
from robofailring.memory.signals.derived import Derivation
from robofailring.memory.signals.layout import SignalLayout
from robofailring.memory.signals.memory import Rows, TaskSignals
from robofailring.sim import VIEWS, run_episode


def simulated_frames(image_size: int, frames: int) -> list[dict[str, np.ndarray]]:
    with run_episode("pick_cube", "grasp", 3, image_size=image_size, frames=frames) as run:
        return [dict(images) for images in run]


def random_memory(entries: int, folder: Path, frames: list[dict[str, np.ndarray]]) -> FailureMemory:
    """`entries` random pair vectors of the pixels encoder's size, one task, real start/end images."""
    encoder = load_encoder("pixels")
    rng = np.random.default_rng(0)
    half = encoder.dim
    vectors = pair_vectors(
        rng.standard_normal((entries, half), np.float32),
        rng.standard_normal((entries, half), np.float32),
        pairing="concat",
    )
    images = []
    for index in range(8):  # a few distinct reference images, shared round-robin
        path = folder / f"ref{index}.png"
        write_png(path, frames[(index * 5) % len(frames)][VIEWS[index % len(VIEWS)]])
        images.append(str(path))
    listed = [
        MemoryEntry(
            task="pick_cube",
            symbol="grasp_wp2",
            episode=f"ep{i // 3}",
            view=VIEWS[i % 3],
            start=images[i % len(images)],
            end=images[(i + 1) % len(images)],
        )
        for i in range(entries)
    ]
    return FailureMemory(vectors, listed, encoder=encoder.identity)


def signal_task(entries: int) -> TaskSignals:
    """A task's signal memory of the simulator's shape (7 joints and a gripper; a 7-d action and a gripper
    command), derived features `change,events`, with `entries` random failure and success entries."""
    rng = np.random.default_rng(0)
    layout = SignalLayout(
        state=(("joints", tuple(f"j{i}" for i in range(7))), ("gripper", ("width",))),
        action=(("action", (*(f"a{i}" for i in range(7)), "grip")),),
        derived=("change", "events"),
    )
    columns = sum(layout.widths)
    runs = []
    for _ in range(10):  # success runs whose gripper and command jump once, half-way
        run = np.cumsum(rng.normal(0, 0.01, (60, columns + 1)), axis=0)
        run[30:, [7, 15]] += 0.04
        run[:, -1] = np.arange(60)
        runs.append(run)
    derivation = Derivation.fit(layout.derived, columns, runs)
    empty = TaskSignals(layout, np.zeros(0), np.ones(0), {}, {}, derivation)
    stacked = np.concatenate([empty.derived(run) for run in runs])
    mean, scale = stacked.mean(axis=0), np.maximum(stacked.std(axis=0), 1e-3)
    width = TaskSignals(layout, mean, scale, {}, {}, derivation).vectors_of(runs[0]).shape[1]
    rows = Rows(np.asarray(["ep"] * entries), np.asarray([""] * entries), np.arange(entries))
    vectors = {
        kind: rng.standard_normal((entries, width)).astype(np.float32) for kind in ("failure", "success")
    }
    return TaskSignals(layout, mean, scale, vectors, {"failure": rows, "success": rows}, derivation, 0.0)


def signal_steps(steps: int, entries: int) -> None:
    """ms per live signal step (`SignalHistory.step`: derived features, pairing, both searches) at step 10
    and at step `steps` (the medians of steps 10 to 59 and of the last 50), and the process's peak RSS then."""
    task = signal_task(entries)
    history = SignalHistory(task)
    rng = np.random.default_rng(1)
    signals = [
        {
            "joints": rng.normal(0, 0.1, 7),
            "gripper": rng.normal(0.04, 0.01, 1),
            "action": rng.normal(0, 0.1, 8),
        }
        for _ in range(64)
    ]
    timed: dict[int, list[float]] = {10: [], steps: []}
    rss_at: dict[int, float] = {}
    for step in range(1, steps + 1):
        started = time.perf_counter()
        history.step(signals[step % len(signals)], exclude_episode=None)
        elapsed = (time.perf_counter() - started) * 1000
        if 10 <= step < 60:  # the 50 steps from step 10 …
            timed[10].append(elapsed)
        if steps - 50 < step:  # … and the 50 up to the last
            timed[steps].append(elapsed)
        if step in (60, steps):
            rss_at[10 if step == 60 else steps] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"live signal step, {entries} failure and {entries} success entries, {steps:,} steps")
    print(f"{'':>22} {'at step 10':>11} {f'at step {steps:,}':>16}")
    print(
        f"{'median ms/step':>22} {statistics.median(timed[10]):>11.3f} {statistics.median(timed[steps]):>16.3f}"
    )
    print(f"{'peak RSS MiB':>22} {rss_at[10]:>11.0f} {rss_at[steps]:>16.0f}")


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--image-size", type=int, default=128)
    parser.add_argument(
        "--entries", type=int, default=1500, help="memory entries (the map is fitted on them)"
    )
    parser.add_argument("--connect", default=None, help="also stream to a running viewer at this URL")
    parser.add_argument("--signal-steps", type=int, default=40_000, help="the live signal session's length")
    parser.add_argument("--signals-only", action="store_true", help="only the signal steps (no cameras)")
    args = parser.parse_args()
    print_machine()
    signal_steps(args.signal_steps, args.entries)
    if args.signals_only:
        return

    frames = simulated_frames(args.image_size, 40)
    with tempfile.TemporaryDirectory(prefix="bench-live-") as tmp:
        folder = Path(tmp)
        memory = random_memory(args.entries, folder, frames)
        started = time.perf_counter()
        memory_map = fit_map(memory)
        fit_s = time.perf_counter() - started
        detector = FailureDetector(memory, load_encoder("pixels"), delta=1.0, k=5)  # δ = 1: no alarm
        target = LiveTarget(connect=args.connect, save=folder / "live.rrd")
        plain = detector.session("pick_cube")
        without: list[float] = []
        with_sink: list[float] = []
        with LiveRecording.open(
            detector, "pick_cube", views=VIEWS, target=target, memory_map=memory_map
        ) as live:
            sunk = detector.session("pick_cube", sink=live)
            for step in range(args.steps + 10):
                images = frames[step % len(frames)]
                t0 = time.perf_counter()
                plain.step(images)
                t1 = time.perf_counter()
                sunk.step(images)
                t2 = time.perf_counter()
                if step >= 10:  # warm-up steps are not counted
                    without.append((t1 - t0) * 1000)
                    with_sink.append((t2 - t1) * 1000)
        size_kib = (folder / "live.rrd").stat().st_size / 1024

    added = [b - a for a, b in zip(without, with_sink, strict=True)]
    print(
        f"live step, {len(VIEWS)} views of {args.image_size}px, memory {args.entries} entries "
        f"(map fitted in {fit_s:.1f} s), {args.steps} steps, sink: file"
        + (f" + viewer {args.connect}" if args.connect else "")
    )
    print(f"{'':>22} {'median ms':>10} {'p95 ms':>8}")
    print(f"{'step without sink':>22} {statistics.median(without):>10.2f} {percentile(without, 95):>8.2f}")
    print(f"{'step with sink':>22} {statistics.median(with_sink):>10.2f} {percentile(with_sink, 95):>8.2f}")
    print(f"{'added by the sink':>22} {statistics.median(added):>10.2f} {percentile(added, 95):>8.2f}")
    print(
        f"recording: {size_kib:.0f} KiB for {args.steps + 10} steps ({size_kib / (args.steps + 10):.1f} KiB/step)"
    )


if __name__ == "__main__":
    main()
