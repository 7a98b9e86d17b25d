"""Both memories at real-robot scale (issue 14): build time, index RAM, 3-view step latency, error.

Run: .venv/bin/python bench/bench_scale.py [--sizes 10k,100k,1M] [--tasks 4] [--threads N]

Synthetic success memories (bench/_synthetic_runs.py: smooth 1024-d runs on the unit sphere,
3 views × 600 frames per run, grouped by task) are indexed per task with exact search (`flat`)
and with the approximate `ivf_sq8` (robofailring.memory.index), side by side, beside a 150k-entry
failure memory (80 tasks, flat). A step searches the 3 views of one frame in one Faiss call per
memory. Exact S⁺ comes from Faiss's brute force (`faiss.knn`, what IndexFlatIP.search
runs) on held-out runs (half of them bent away from every success, like failures). Data are
generated one task at a time and freed once indexed. The last line reads
`scale 1M: median <ms> ms, p95 <ms> ms, max_abs_err <x>, index_gb <x>`.
"""

from __future__ import annotations

import argparse
import gc
import statistics
import time
from collections.abc import Callable

import faiss
import numpy as np
from _synthetic_runs import HALF, VIEWS, describe, held_out_steps, task_memory

from robofailring.memory.index import IVF_SQ8, TaskIndex, TaskIndexSet, choose_spec
from robofailring.memory.pairs import pair_vectors

DIM = 2 * HALF
NPROBES = (4, 8, 16, 32, 64)


def rss_gb() -> float:
    with open("/proc/self/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 2**20
    return float("nan")


class Times(list[float]):
    """Wall milliseconds per step, with the thread's CPU milliseconds beside them in `cpu`.

    On this shared machine a step's wall time includes waiting for a core; its CPU time does not.
    """

    def __init__(self) -> None:
        super().__init__()
        self.cpu: list[float] = []

    def __add__(self, other: list[float]) -> Times:  # type: ignore[override]
        joined = Times()
        joined.extend([*self, *other])
        joined.cpu = self.cpu + getattr(other, "cpu", [])
        return joined


def latencies(run: Callable[[int], object], count: int) -> Times:
    times = Times()
    for step in range(count):
        start, start_cpu = time.perf_counter(), time.thread_time()
        run(step)
        times.append((time.perf_counter() - start) * 1000)
        times.cpu.append((time.thread_time() - start_cpu) * 1000)
    return times


def summary(times: Times) -> str:
    return (
        f"median {statistics.median(times):.3f} ms, p95 {np.percentile(times, 95):.3f} ms "
        f"(CPU median {statistics.median(times.cpu):.3f} ms, p95 {np.percentile(times.cpu, 95):.3f} ms)"
    )


def parse_size(text: str) -> int:
    text = text.strip().lower()
    factor = {"k": 1_000, "m": 1_000_000}.get(text[-1], 1)
    return int(float(text.rstrip("km")) * factor)


# ---------------------------------------------------------------- failure memory
def failure_memory(entries: int, tasks: int) -> tuple[TaskIndexSet, np.ndarray, list[str]]:
    """Random start‖end pairs (as bench_core.py), `entries` over `tasks` tasks; flat per task."""
    rng = np.random.default_rng(0)
    vectors = np.empty((entries, DIM), np.float32)
    for offset in range(0, entries, 25_000):
        count = min(25_000, entries - offset)
        vectors[offset : offset + count] = pair_vectors(
            rng.standard_normal((count, HALF), np.float32),
            rng.standard_normal((count, HALF), np.float32),
            pairing="concat",
        )
    task_of = [f"task_{(i // VIEWS) % tasks}" for i in range(entries)]
    episodes = [f"ep{i // VIEWS}" for i in range(entries)]
    start = time.perf_counter()
    memory = TaskIndexSet.build(vectors, task_of, episodes, kind="flat")
    print(
        f"failure memory: {entries:,} entries, {tasks} tasks, flat, built in {time.perf_counter() - start:.1f} s"
    )
    queries = pair_vectors(
        rng.standard_normal((300 * VIEWS, HALF)), rng.standard_normal((300 * VIEWS, HALF)), pairing="concat"
    )
    return memory, queries.reshape(300, VIEWS, DIM), [f"task_{i % tasks}" for i in range(300)]


def bench_failure(memory: TaskIndexSet, steps: np.ndarray, tasks: list[str]) -> None:
    count = len(steps)
    separate = latencies(lambda i: [memory.search(q, tasks[i], 5) for q in steps[i]], count)
    together = latencies(lambda i: memory.search(steps[i], tasks[i], 5), count)
    separate += latencies(lambda i: [memory.search(q, tasks[i], 5) for q in steps[i]], count)
    together += latencies(lambda i: memory.search(steps[i], tasks[i], 5), count)
    excluded = latencies(lambda i: memory.search(steps[i], tasks[i], 5, exclude_episode="ep7"), count)
    print(f"failure memory 3-view step, 3 calls: {summary(separate)}")
    print(f"failure memory 3-view step, 1 call:  {summary(together)} (target <= 1 ms)")
    print(f"failure memory 3-view step, 1 call, leave-one-out IDSelector: {summary(excluded)}")


def bench_one_filtered_index(entries: int, tasks: int, steps: np.ndarray, task_names: list[str]) -> None:
    """The alternative to per-task indexes: one flat index, the task as an IDSelectorRange."""
    rng = np.random.default_rng(0)
    index = faiss.IndexFlatIP(DIM)
    per_task = entries // tasks
    for _ in range(tasks):  # rows of a task are contiguous, so a range selects it
        index.add(
            pair_vectors(
                rng.standard_normal((per_task, HALF)), rng.standard_normal((per_task, HALF)), pairing="concat"
            )
        )
    selectors = [faiss.IDSelectorRange(t * per_task, (t + 1) * per_task) for t in range(tasks)]
    params = [faiss.SearchParameters(sel=selector) for selector in selectors]

    def step(i: int) -> None:
        index.search(steps[i], 5, params=params[int(task_names[i].split("_")[1])])

    print(
        f"failure memory 3-view step, one flat index + IDSelectorRange per task: {summary(latencies(step, len(steps)))}"
    )


# ---------------------------------------------------------------- success memory
def hnsw_probe(count: int = 20_000) -> None:
    vectors = np.concatenate([v for v, _ in task_memory(0, count)])
    index = faiss.IndexHNSWFlat(DIM, 32, faiss.METRIC_INNER_PRODUCT)
    start = time.perf_counter()
    index.add(vectors)
    seconds = time.perf_counter() - start
    per_million = seconds * 1_000_000 / count * np.log(1_000_000) / np.log(count)
    print(
        f"HNSW32 probe: {count:,} × {DIM}-d built in {seconds:.1f} s -> about {per_million / 60:.0f} min for 1M "
        f"(n log n), and {1_000_000 * (DIM * 4 + 32 * 2 * 4) / 1e9:.1f} GB of vectors and links"
    )


def crossover(sizes: tuple[int, ...] = (1_000, 2_000, 5_000, 10_000, 20_000, 50_000)) -> None:
    """Flat vs ivf_sq8 3-view step for one task of each size: where `auto` should switch."""
    print("\n task entries | flat step median (CPU) | ivf_sq8 step median (CPU) | ivf_sq8 S+ max_abs_err")
    held = held_out_steps(0, 60, deviate=0.0)
    exact = held.reshape(-1, DIM)
    for size in sizes:
        vectors = np.concatenate([chunk for chunk, _ in task_memory(0, size)])
        episodes = [str(i // 600) for i in range(size)]
        flat = TaskIndex.build(vectors, np.arange(size), episodes, choose_spec(size, kind="flat"))
        approximate = TaskIndex.build(vectors, np.arange(size), episodes, choose_spec(size, kind=IVF_SQ8))
        flat_times = latencies(lambda i, flat=flat: flat.search(held[i % 60], 1), 120)
        approx_times = latencies(lambda i, approximate=approximate: approximate.search(held[i % 60], 1), 120)
        error = np.abs(approximate.search(exact, 1)[0] - flat.search(exact, 1)[0]).max()
        print(
            f" {size:12,d} | {statistics.median(flat_times):.3f} ms ({statistics.median(flat_times.cpu):.3f}) | "
            f"{statistics.median(approx_times):.3f} ms ({statistics.median(approx_times.cpu):.3f}) | {error:.5f}"
        )


def bench_success(
    size: int, tasks: int, steps_per_task: int, failures: tuple[TaskIndexSet, list[str]] | None
) -> dict[str, float]:
    per_task = size // tasks
    spec = choose_spec(per_task, kind=IVF_SQ8)
    auto = choose_spec(per_task)
    print(f"\n== success memory {size:,} entries: {tasks} tasks × {per_task:,}; auto picks {auto.to_dict()}")
    exact: list[tuple[np.ndarray, np.ndarray]] = []
    queries: list[np.ndarray] = []
    approximate: dict[str, TaskIndex] = {}
    flat_times = Times()
    build_flat = build_approx = 0.0
    gc.collect()
    rss_before = rss_gb()
    for task in range(tasks):
        vectors = np.empty((per_task, DIM), np.float32)
        runs = np.empty(per_task, np.int64)
        filled = 0
        for chunk, run in task_memory(task, per_task):
            vectors[filled : filled + len(chunk)] = chunk
            runs[filled : filled + len(chunk)] = run
            filled += len(chunk)
        half = steps_per_task // 2
        held = np.concatenate(
            [
                held_out_steps(task, half, deviate=0.0),
                held_out_steps(task + 100, steps_per_task - half, deviate=1.0),
            ]
        )
        queries.append(held)
        sims, ids = faiss.knn(held.reshape(-1, DIM), vectors, 1, metric=faiss.METRIC_INNER_PRODUCT)
        exact.append((sims[:, 0].reshape(-1, VIEWS), ids[:, 0].reshape(-1, VIEWS)))
        if task == 0:  # exact 3-view step: flat over this task's entries
            start = time.perf_counter()
            flat = TaskIndex.build(
                vectors, np.arange(per_task), runs.astype(str).tolist(), choose_spec(per_task, kind="flat")
            )
            build_flat = time.perf_counter() - start
            repeat = int(min(len(held), max(10, 2e7 / per_task)))
            flat_times = latencies(lambda i, flat=flat, held=held: flat.search(held[i], 1), repeat)
            del flat
        start = time.perf_counter()
        approximate[f"task_{task}"] = TaskIndex.build(
            vectors, np.arange(per_task), runs.astype(str).tolist(), spec
        )
        build_approx += time.perf_counter() - start
        del vectors, runs
        gc.collect()
    memory = TaskIndexSet(approximate)
    rss = rss_gb() - rss_before
    print(f"build: flat {build_flat * tasks:.1f} s (one task × {tasks}), ivf_sq8 {build_approx:.1f} s")
    print(
        f"index RAM: flat {size * DIM * 4 / 2**30:.2f} GB, ivf_sq8 {memory.nbytes / 2**30:.3f} GB "
        f"(Faiss arrays; process RSS grew {rss:.3f} GB)"
    )
    print(f"exact 3-view step (flat, {per_task:,} entries, {len(flat_times)} steps): {summary(flat_times)}")
    steps = np.concatenate(queries)
    step_task = [f"task_{i // steps_per_task}" for i in range(len(steps))]
    exact_sims = np.concatenate([s for s, _ in exact])
    exact_ids = np.concatenate([i for _, i in exact])
    order = np.random.default_rng(3).permutation(len(steps))
    print(
        " nprobe | success step wall median  p95 | CPU median  p95 | S+ max_abs_err  p99_abs_err | top-1 agree"
    )
    result: dict[str, float] = {}
    for nprobe in sorted({*NPROBES, spec.nprobe}):
        for index in approximate.values():
            index.index.nprobe = nprobe
        times = latencies(lambda i: memory.search(steps[order[i]], step_task[order[i]], 1), len(steps))
        results = [memory.search(steps[i], step_task[i], 1) for i in range(len(steps))]
        found = np.stack([sims[:, 0] for sims, _ in results])
        found_ids = np.stack([ids[:, 0] for _, ids in results])
        error = np.abs(found - exact_sims)
        marker = " <- default" if nprobe == spec.nprobe else ""
        print(
            f" {nprobe:6d} | {statistics.median(times):8.3f} ms {np.percentile(times, 95):8.3f} ms | "
            f"{statistics.median(times.cpu):6.3f} {np.percentile(times.cpu, 95):6.3f} ms | "
            f"{error.max():.5f}  {np.percentile(error, 99):.5f} | {np.mean(found_ids == exact_ids):.3f}{marker}"
        )
        if nprobe == spec.nprobe:
            result = {"max_abs_err": float(error.max()), "index_gb": memory.nbytes / 2**30}
    for index in approximate.values():
        index.index.nprobe = spec.nprobe
    step = latencies(lambda i: memory.search(steps[order[i]], step_task[order[i]], 1), len(steps))
    print(f"approximate 3-view success step (ivf_sq8, nprobe {spec.nprobe}): {summary(step)}")
    if failures is not None:
        failure_set, failure_tasks = failures
        failure_steps = steps  # any unit 1024-d vectors: the failure search cost does not depend on them

        def both(i: int) -> None:
            j = order[i]
            failure_set.search(failure_steps[j], failure_tasks[j % len(failure_tasks)], 5)
            memory.search(steps[j], step_task[j], 1)

        combined = latencies(both, len(steps)) + latencies(both, len(steps))
        result.update(median=statistics.median(combined), p95=float(np.percentile(combined, 95)))
        print(
            f"3-view step, both memories (failure flat {len(failure_set):,} + success ivf_sq8 {size:,}): {summary(combined)}"
        )
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10k,100k,1M", help="success memory sizes, e.g. 10k,100k")
    parser.add_argument("--tasks", type=int, default=4, help="tasks the success entries are spread over")
    parser.add_argument("--steps", type=int, default=100, help="held-out 3-view steps per task")
    parser.add_argument("--failures", type=int, default=150_000, help="failure memory entries (0: none)")
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="Faiss OpenMP threads (1: a step is 3 queries; 0: Faiss's default)",
    )
    parser.add_argument("--hnsw-probe", action="store_true", help="time an HNSW build on 20k entries")
    parser.add_argument("--crossover", action="store_true", help="flat vs ivf_sq8 per task size, 1k to 50k")
    args = parser.parse_args()
    if args.threads:
        faiss.omp_set_num_threads(args.threads)
    print(f"Faiss {faiss.__version__}, {faiss.omp_get_max_threads()} OpenMP threads; {describe()}")
    if args.hnsw_probe:
        hnsw_probe()
    if args.crossover:
        crossover()
    failures = None
    if args.failures:
        memory, steps, tasks = failure_memory(args.failures, 80)
        bench_failure(memory, steps, tasks)
        bench_one_filtered_index(args.failures, 80, steps, tasks)
        gc.collect()
        failures = (memory, tasks)
    results = {}
    for text in filter(None, args.sizes.split(",")):
        size = parse_size(text)
        results[size] = bench_success(size, args.tasks, args.steps, failures)
        gc.collect()
    if 1_000_000 in results and "median" in results[1_000_000]:
        r = results[1_000_000]
        print(
            f"scale 1M: median {r['median']:.3f} ms, p95 {r['p95']:.3f} ms, "
            f"max_abs_err {r['max_abs_err']:.4f}, index_gb {r['index_gb']:.3f}"
        )


if __name__ == "__main__":
    main()
