"""The demo before and after jobs pass values (issue 32, item 3): the same small demo timed under a baseline
commit's code and under this checkout's, in one run, and the ratio.

Run: .venv/bin/python -m bench.bench_demo_reuse [--baseline COMMIT] [--repeats 2] [--episodes 2] [--frames 8]

The baseline's source is exported with `git archive` (no worktree, nothing of the repository changed) into
a temporary folder; each demo runs in a fresh Python process with that tree (or this checkout) first on
`PYTHONPATH`. Both read the same simulated datasets and trained encoder (simulated and trained once, by an
untimed warm-up run), and each timed run starts from an empty embedding cache, so every frame either code
encodes is encoded in the timing. Runs alternate (baseline, new, baseline, new, …); the medians are
compared, wall-clock and CPU time (user + system of the demo's own process: less swayed by other work on
a shared machine). Before: the demo built, calibrated and evaluated its headline memory once more inside the
encoder comparison, and re-opened a detector and re-scored each trajectory it recorded. After: the
comparison takes the headline's result, and the recordings reuse the evaluation's traces (their map
points placed while they were scored).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench._timing import print_machine

ROOT = Path(__file__).resolve().parents[1]

RUN = """
import json, resource, sys, time
from collections import Counter
from pathlib import Path
import rfr_viz.panels.umap as umap_panel
import robofailring.calibration.job as calibration
import robofailring.evaluation.job as evaluation
from robofailring.detection.detector import FailureDetector
from robofailring.memory.failure import FailureMemory

work = Counter()  # what the demo did, counted where it is done (patched before the jobs import it)

def counted(owner, name, key, frames=None):
    real = getattr(owner, name)
    def wrapper(*args, **kwargs):
        work[key] += 1
        if frames is not None:
            work[key + " frames"] += frames(*args)
        return real(*args, **kwargs)
    setattr(owner, name, wrapper)

counted(FailureDetector, "run", "detector runs", lambda self, trajectory, *a: min(len(f) for f in trajectory.views.values()))
counted(FailureMemory, "load", "memory loads")
counted(umap_panel, "fit_map", "map fits")
counted(evaluation, "run_evaluation", "evaluations")
counted(evaluation, "build_training_memory", "memory builds")
counted(calibration, "calibrate", "calibrations")
from rfr_viz.jobs.demo import DemoConfig, run_demo
from robofailring.encoders.placement import EncoderPlacement
from robofailring.calibration.policy import ThresholdPolicy
settings = json.loads(sys.argv[1])
config = DemoConfig(
    out=Path(settings["out"]), data_dir=Path(settings["data"]), placement=EncoderPlacement(cache_dir=Path(settings["cache"])),
    tasks=("pick_cube",), episodes=settings["episodes"], success_episodes=2 * settings["episodes"],
    ood_episodes=1, image_size=32, frames=settings["frames"], workers=1, threshold_policy=ThresholdPolicy(0.5), randomize=8,
    trained_epochs=2,
)
def cpu():
    used = resource.getrusage(resource.RUSAGE_SELF)
    return used.ru_utime + used.ru_stime
start, start_cpu = time.perf_counter(), cpu()
result = run_demo(config, say=lambda line: None)
print(json.dumps({
    "seconds": time.perf_counter() - start,
    "cpu": cpu() - start_cpu,
    "work": dict(sorted(work.items())),
    "recordings": sorted(result.recordings),
    "comparison": result.comparison is not None,
    "recall": {e.name: {r: row.recall for r, row in e.rules.items()} for e in result.evaluations},
}))
"""


def export(commit: str, into: Path) -> Path:
    """The tree of `commit` written under `into` (git archive: the repository is left as it is)."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], check=True, capture_output=True)
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive.stdout, check=True)
    return into


def run_demo(tree: Path, settings: dict[str, object]) -> dict[str, object]:
    """One demo in a fresh process with `tree`'s code first on the path; its own timing and outcome."""
    env = {**os.environ, "PYTHONPATH": f"{tree / 'src'}{os.pathsep}{tree}"}
    done = subprocess.run(
        [sys.executable, "-c", RUN, json.dumps(settings)], env=env, capture_output=True, text=True, cwd=tree
    )
    if done.returncode != 0:
        raise SystemExit(f"the demo under {tree} failed:\n{done.stderr[-3000:]}")
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default="51010c0", help="commit of the code before (default: main's)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--episodes", type=int, default=2, help="in-distribution episodes per kind")
    parser.add_argument("--frames", type=int, default=8, help="frames per simulated episode")
    args = parser.parse_args()
    print_machine()
    with tempfile.TemporaryDirectory(prefix="rfr-bench-demo-") as tmp:
        work = Path(tmp)
        baseline = work / "baseline"
        baseline.mkdir()
        export(args.baseline, baseline)
        data = work / "data"
        common = {"data": str(data), "episodes": args.episodes, "frames": args.frames}
        warm = run_demo(ROOT, {**common, "out": str(work / "warm"), "cache": str(work / "cache-warm")})
        print(f"warm-up (simulation and the trained encoder, untimed): {warm['seconds']:.1f} s")
        times: dict[str, list[float]] = {"baseline": [], "new": []}
        cpu: dict[str, list[float]] = {"baseline": [], "new": []}
        for repeat in range(args.repeats):
            for name, tree in (("baseline", baseline), ("new", ROOT)):
                settings = {
                    **common,
                    "out": str(work / f"{name}-{repeat}"),
                    "cache": str(work / f"cache-{name}-{repeat}"),
                }
                start = time.perf_counter()
                found = run_demo(tree, settings)
                wall = time.perf_counter() - start
                times[name].append(float(found["seconds"]))  # type: ignore[arg-type]
                cpu[name].append(float(found["cpu"]))  # type: ignore[arg-type]
                print(
                    f"{name:>8} #{repeat + 1}: run_demo {found['seconds']:.1f} s wall, {found['cpu']:.1f} s CPU "
                    f"(process {wall:.1f} s), "
                    f"recordings {found['recordings']}, comparison {found['comparison']}, recall {found['recall']}"
                )
                print(f"{'':>12}work: {found['work']}")
        for label, found_times in (("wall", times), ("CPU", cpu)):
            before, after = statistics.median(found_times["baseline"]), statistics.median(found_times["new"])
            print(
                f"median run_demo {label}: baseline {before:.1f} s, new {after:.1f} s, "
                f"ratio baseline/new = {before / after:.2f}"
            )


if __name__ == "__main__":
    main()
