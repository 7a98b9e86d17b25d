"""Timing helpers shared by the bench scripts: the median of repeated calls, and the machine a run measured on."""

from __future__ import annotations

import atexit
import importlib
import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Libraries whose version (and thread count, where they have one) a machine line names once a bench has
# imported them; a bench names more with `libraries`.
REPORTED = ("torch", "faiss", "onnxruntime", "cv2", "open_clip", "timm", "rerun", "av")


def median_ms(run: Callable[[], object], repeat: int) -> float:
    """Median wall time of `run` over `repeat` calls, in milliseconds."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        times.append((time.perf_counter() - start) * 1000)
    return statistics.median(times)


def cpu_model() -> str:
    """The CPU's model name as the kernel reports it (a VM may report only the family)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def load_average() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load {one:.2f} / {five:.2f} / {fifteen:.2f} (1 / 5 / 15 min)"


def _library(name: str) -> str:
    module = sys.modules[name]
    version = getattr(module, "__version__", "?")
    threads = {
        "torch": lambda: module.get_num_threads(),
        "faiss": lambda: module.omp_get_max_threads(),
        "cv2": lambda: module.getNumThreads(),
    }.get(name)
    if threads is None:
        return f"{name} {version}"
    count = threads()
    return f"{name} {version} ({count} thread{'' if count == 1 else 's'})"


def _commit() -> str:
    try:
        found = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return found.stdout.strip() + ("+changes" if dirty.stdout.strip() else "") or "unknown"


def machine_line(*, libraries: Sequence[str] = ()) -> str:
    """What a run measured on: CPU model, cores (usable), RAM, load, Python and libraries with their threads.

    `libraries` are imported to be named; any of REPORTED the bench has imported already is named too.
    """
    for name in libraries:
        importlib.import_module(name)
    named = [_library(name) for name in dict.fromkeys([*libraries, *REPORTED]) if name in sys.modules]
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    omp = os.environ.get("OMP_NUM_THREADS")
    return (
        f"machine: {cpu_model()}, {os.cpu_count()} cores ({usable} usable), {memory:.0f} GiB RAM; "
        f"{load_average()}; Python {platform.python_version()}, numpy {_numpy_version()}"
        + "".join(f", {entry}" for entry in named)
        + (f"; OMP_NUM_THREADS={omp}" if omp else "")
        + f"; commit {_commit()}"
    )


def _numpy_version() -> str:
    import numpy

    return numpy.__version__


def print_machine(*, libraries: Sequence[str] = ()) -> None:
    """Print `machine_line()` now and the load average again when the run ends (the load it ran under)."""
    print(machine_line(libraries=libraries), flush=True)
    atexit.register(lambda: print(f"machine at the end: {load_average()}", flush=True))
