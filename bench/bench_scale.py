"""Both memories at real-robot scale (issues 14, 34): build, index RAM, 3-view step, bytes read, error.

Run: .venv/bin/python -m bench.bench_scale [--sizes 10k,100k,1M] [--tasks 4] [--kinds ivf_pqfs,ivf_sq8]

Synthetic success memories (bench/_synthetic_runs.py: smooth 1024-d runs on the unit sphere,
3 views × 600 frames per run, grouped by task) are indexed per task with exact search (`flat`,
one task) and with each approximate kind (robofailring.memory.index), side by side, beside a
150k-entry failure memory (80 tasks, flat). A step searches the 3 views of one frame in one Faiss
call per memory. Exact S⁺ comes from Faiss's brute force (`faiss.knn`) on held-out runs (half of
them bent away from every success, like failures). Every setting prints the bytes a query reads
(bench/_read_bytes.py) and the step's limit at the memory bandwidth measured in the same run,
beside the failure memory's step timed just before. Data are generated one task at a time and
freed once indexed. The last line reads `scale 1M: median <ms> ms, p95 <ms> ms, max_abs_err <x>,
index_gb <x>; success step <ms> ms = <x>x its bandwidth limit, <x>x the failure step`.
"""

from __future__ import annotations

import argparse
import gc
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import faiss
import numpy as np

from bench._read_bytes import bytes_per_query, limit_line, memory_bandwidth
from bench._synthetic_runs import HALF, VIEWS, describe, held_out_steps, task_memory
from bench._timing import print_machine
from robofailring.memory.index import FLAT, IVF_PQFS, IVF_SQ8, IndexSpec, TaskIndex, TaskIndexSet, choose_spec
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


@dataclass
class Failures:
    """The failure memory, its queries and its 1-call 3-view step (median ms and bytes it reads)."""

    memory: TaskIndexSet
    steps: np.ndarray
    tasks: list[str]
    step_ms: float = float("nan")
    step_bytes: float = float("nan")

    def time_step(self) -> None:
        count = len(self.steps)
        times = latencies(lambda i: self.memory.search(self.steps[i], self.tasks[i], 5), count)
        self.step_ms = statistics.median(times)
        self.step_bytes = VIEWS * float(
            np.mean([bytes_per_query(self.memory.by_task[t], self.steps[0]) for t in self.tasks])
        )


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
    """Flat vs the approximate kinds' 3-view step for one task of each size: where `auto` should switch."""
    kinds = (IVF_PQFS, IVF_SQ8)
    print(
        "\n task entries | flat step median (CPU) | "
        + " | ".join(f"{k} step median (CPU), S+ max_abs_err" for k in kinds)
    )
    held = held_out_steps(0, 60, deviate=0.0)
    exact = held.reshape(-1, DIM)
    for size in sizes:
        vectors = np.concatenate([chunk for chunk, _ in task_memory(0, size)])
        episodes = [str(i // 600) for i in range(size)]
        flat = TaskIndex.build(vectors, np.arange(size), episodes, IndexSpec("flat"))
        cells = [_median_cell(latencies(lambda i, flat=flat: flat.search(held[i % 60], 1), 120))]
        for kind in kinds:
            index = TaskIndex.build(vectors, np.arange(size), episodes, choose_spec(size, kind=kind, dim=DIM))
            times = latencies(lambda i, index=index: index.search(held[i % 60], 1), 120)
            error = np.abs(index.search(exact, 1)[0] - flat.search(exact, 1)[0]).max()
            cells.append(f"{_median_cell(times)}, {error:.5f}")
        print(f" {size:12,d} | " + " | ".join(cells))


def _median_cell(times: Times) -> str:
    return f"{statistics.median(times):.3f} ms ({statistics.median(times.cpu):.3f})"


def sweep(kind: str, spec: IndexSpec) -> list[dict[str, int]]:
    """Search settings to time for `kind`: nprobe, and for ivf_pqfs the candidates re-ranked.

    nprobe is capped at the index's nlist (every list): a small task has fewer lists than the sweep's
    largest nprobe, and Faiss's fast-scan IVF does not cap it itself (its results are garbage above nlist).
    """
    if kind == IVF_SQ8:
        return [{"nprobe": n} for n in sorted({min(n, spec.nlist) for n in (*NPROBES, spec.nprobe)})]
    settings = [(8, 64), (16, 32), (16, 64), (16, 128), (32, 64), (spec.nprobe, spec.k_factor)]
    return [{"nprobe": n, "k_factor": k} for n, k in sorted({(min(n, spec.nlist), k) for n, k in settings})]


def tune(index: TaskIndex, nprobe: int, k_factor: int = 0) -> None:
    """Search `index` with `nprobe` lists (and `k_factor`); IndexSpec refuses an nprobe above nlist."""
    spec = replace(index.spec, nprobe=nprobe, k_factor=k_factor if index.spec.kind == IVF_PQFS else 0)
    if spec.kind == IVF_PQFS:
        index.index.k_factor = spec.k_factor
        faiss.downcast_index(index.index.base_index).nprobe = spec.nprobe
    else:
        index.index.nprobe = spec.nprobe


def accuracy(
    memory: TaskIndexSet,
    steps: np.ndarray,
    step_task: list[str],
    exact_sims: np.ndarray,
    exact_ids: np.ndarray,
) -> tuple[np.ndarray, float, float]:
    """S⁺ absolute errors of every step's views, the share whose top-1 is the exact one, bytes read a query."""
    results = [memory.search(steps[i], step_task[i], 1) for i in range(len(steps))]
    found = np.stack([sims[:, 0] for sims, _ in results])
    found_ids = np.stack([ids[:, 0] for _, ids in results])
    read = np.mean([bytes_per_query(memory.by_task[t], steps[i]) for i, t in enumerate(step_task)])
    return np.abs(found - exact_sims), float(np.mean(found_ids == exact_ids)), float(read)


def bench_success(
    size: int, tasks: int, steps_per_task: int, kinds: list[str], failures: Failures | None
) -> dict[str, float]:
    per_task = size // tasks
    auto = choose_spec(per_task, dim=DIM)
    if auto.kind != FLAT:  # the index a deployment gets is always built, whatever --kinds says
        kinds = list(dict.fromkeys([*kinds, auto.kind]))
    specs = {kind: choose_spec(per_task, kind=kind, dim=DIM) for kind in kinds}
    print(f"\n== success memory {size:,} entries: {tasks} tasks × {per_task:,}; auto picks {auto.to_dict()}")
    exact: list[tuple[np.ndarray, np.ndarray]] = []
    queries: list[np.ndarray] = []
    approximate: dict[str, dict[str, TaskIndex]] = {kind: {} for kind in kinds}
    exact_by_task: dict[str, TaskIndex] = {}  # every task's flat index, when auto keeps the tasks exact
    flat_times = Times()
    build_flat, build = 0.0, dict.fromkeys(kinds, 0.0)
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
        episodes = runs.astype(str).tolist()
        if task == 0 or auto.kind == FLAT:  # exact 3-view step: flat over this task's entries
            start = time.perf_counter()
            flat = TaskIndex.build(vectors, np.arange(per_task), episodes, IndexSpec(FLAT))
            if task == 0:
                build_flat = time.perf_counter() - start
                repeat = int(min(len(held), max(10, 2e7 / per_task)))
                flat_times = latencies(lambda i, flat=flat, held=held: flat.search(held[i], 1), repeat)
            if auto.kind == FLAT:
                exact_by_task[f"task_{task}"] = flat
            del flat
        for kind, spec in specs.items():
            start = time.perf_counter()
            approximate[kind][f"task_{task}"] = TaskIndex.build(vectors, np.arange(per_task), episodes, spec)
            build[kind] += time.perf_counter() - start
        del vectors, runs
        gc.collect()
    rss = rss_gb() - rss_before
    built = ", ".join(f"{kind} {seconds:.1f} s" for kind, seconds in build.items())
    print(f"build: flat {build_flat * tasks:.1f} s (one task × {tasks}), {built}")
    sets = {kind: TaskIndexSet(indexes) for kind, indexes in approximate.items()}
    ram = ", ".join(f"{kind} {memory.nbytes / 2**30:.3f} GB" for kind, memory in sets.items())
    print(
        f"index RAM: flat {size * DIM * 4 / 2**30:.2f} GB, {ram} (Faiss arrays; process RSS grew {rss:.3f} GB)"
    )
    print(f"exact 3-view step (flat, {per_task:,} entries, {len(flat_times)} steps): {summary(flat_times)}")
    steps = np.concatenate(queries)
    step_task = [f"task_{i // steps_per_task}" for i in range(len(steps))]
    exact_sims = np.concatenate([s for s, _ in exact])
    exact_ids = np.concatenate([i for _, i in exact])
    order = np.random.default_rng(3).permutation(len(steps))
    bandwidth = memory_bandwidth()
    if failures is not None:
        failures.time_step()
    failure_ms = failures.step_ms if failures is not None else float("nan")
    result: dict[str, float] = {}
    for kind, memory in sets.items():
        spec = specs[kind]
        print(
            f" {kind}: setting | bytes/query | bandwidth limit | step wall median  p95 | CPU median | "
            "x limit | x failure | S+ max_abs_err  p99 | top-1 agree"
        )
        for setting in sweep(kind, spec):
            for index in memory.by_task.values():
                tune(index, **setting)
            times = latencies(
                lambda i, memory=memory: memory.search(steps[order[i]], step_task[order[i]], 1), len(steps)
            )
            error, agree, read = accuracy(memory, steps, step_task, exact_sims, exact_ids)
            limit = VIEWS * read / bandwidth * 1000
            median = statistics.median(times)
            default = setting == {"nprobe": spec.nprobe, "k_factor": spec.k_factor} or setting == {
                "nprobe": spec.nprobe
            }
            print(
                f" {' '.join(f'{k} {v}' for k, v in setting.items()):>21} | {read / 2**20:7.3f} MiB | {limit:.3f} ms | "
                f"{median:8.3f} ms {np.percentile(times, 95):8.3f} ms | {statistics.median(times.cpu):6.3f} ms | "
                f"{median / limit:5.2f} | {median / failure_ms:5.2f} | "
                f"{error.max():.5f}  {np.percentile(error, 99):.5f} | {agree:.3f}"
                + (" <- default" if default else "")
            )
            if default and kind == auto.kind:
                result = {"max_abs_err": float(error.max()), "index_gb": memory.nbytes / 2**30}
                result.update(step=median, limit=float(limit), read=float(VIEWS * read))
        for index in memory.by_task.values():
            tune(index, spec.nprobe, spec.k_factor)
    memory = TaskIndexSet(exact_by_task) if auto.kind == FLAT else sets[auto.kind]
    step = latencies(lambda i: memory.search(steps[order[i]], step_task[order[i]], 1), len(steps))
    print(f"auto's 3-view success step ({auto.to_dict()}, every task): {summary(step)}")
    if auto.kind == FLAT:
        error, _, read = accuracy(memory, steps, step_task, exact_sims, exact_ids)
        result = {"max_abs_err": float(error.max()), "index_gb": memory.nbytes / 2**30}
        result.update(limit=VIEWS * read / bandwidth * 1000, read=VIEWS * read)
    print(f"bandwidth: {bandwidth / 1e9:.1f} GB/s (numpy sum over 0.5 GiB, best of 5)")
    if failures is not None:
        result["step"] = statistics.median(step)
        failures.time_step()  # again now, beside the success step (the load on this machine varies)
        print(
            limit_line(
                "150k flat failure step", failures.step_ms, failures.step_bytes, bandwidth, failures.step_ms
            )
        )
        if "read" in result:
            print(
                limit_line(
                    f"{size:,} success step", result["step"], result["read"], bandwidth, failures.step_ms
                )
            )

        def both(i: int) -> None:
            j = order[i]
            failures.memory.search(steps[j], failures.tasks[j % len(failures.tasks)], 5)
            memory.search(steps[j], step_task[j], 1)

        combined = latencies(both, len(steps)) + latencies(both, len(steps))
        result.update(median=statistics.median(combined), p95=float(np.percentile(combined, 95)))
        result["failure"] = failures.step_ms
        print(
            f"3-view step, both memories (failure flat {len(failures.memory):,} + success {size:,}): {summary(combined)}"
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
    parser.add_argument(
        "--kinds", default=f"{IVF_PQFS},{IVF_SQ8}", help="approximate index kinds to build side by side"
    )
    parser.add_argument("--hnsw-probe", action="store_true", help="time an HNSW build on 20k entries")
    parser.add_argument(
        "--crossover", action="store_true", help="flat vs approximate per task size, 1k to 50k"
    )
    args = parser.parse_args()
    if args.threads:
        faiss.omp_set_num_threads(args.threads)
    print_machine()
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
        failures = Failures(memory, steps, tasks)
    results = {}
    for text in filter(None, args.sizes.split(",")):
        size = parse_size(text)
        results[size] = bench_success(size, args.tasks, args.steps, args.kinds.split(","), failures)
        gc.collect()
    if 1_000_000 in results and "median" in results[1_000_000]:
        r = results[1_000_000]
        print(
            f"scale 1M: median {r['median']:.3f} ms, p95 {r['p95']:.3f} ms, "
            f"max_abs_err {r['max_abs_err']:.4f}, index_gb {r['index_gb']:.3f}; success step {r['step']:.3f} ms "
            f"= {r['step'] / r['limit']:.2f}x its bandwidth limit, {r['step'] / r['failure']:.2f}x the failure step"
        )


if __name__ == "__main__":
    main()
