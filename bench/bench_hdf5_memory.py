"""Peak resident memory of reading, detecting on and replaying one robomimic demo (3 cameras), of 500, 2,000 and 4,000 frames.

A robomimic-style file is written with h5py (3 cameras of 84×84 RGB, gzip chunks of one frame, as
robomimic's dataset_states_to_obs writes them); a small memory (one failure, one success, same
task) is built once; then `robofailring detect` and `robofailring replay` (to a `.rrd`) run in a
fresh process per file and report their peak RSS (`resource.getrusage(RUSAGE_SELF).ru_maxrss`).
Frames are rows sliced on demand and scored in chunks (`FailureDetector.run`), and the replay keeps
each query as its map point, not its vector, so the figures should differ by little more than the
per-frame scores. Control: `h5py` reads the same rows in a bare h5py loop, so what libhdf5 itself keeps
per chunk read (its chunk index, ~0.3 KB per one-frame chunk) is told apart from the project's reader. `--codec` is the replay's `--camera-codec` (default auto: AV1 at these sizes), `--lengths`
the demo lengths. Run:

    .venv/bin/python -m bench.bench_hdf5_memory [--codec jpeg] [--lengths 500 2000 4000]
"""

from __future__ import annotations

import argparse
import itertools
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

from bench._timing import print_machine

CAMERAS = ("agentview_image", "robot0_eye_in_hand_image", "sideview_image")
SIZE = 84
LENGTHS = (500, 2000, 4000)  # frames per demo: a longer demo must not need more memory


def frame(demo: int, camera: int, t: int, length: int) -> np.ndarray:
    image = np.full((SIZE, SIZE, 3), 60 + 40 * camera, np.uint8)
    row = int(8 + (t / max(length - 1, 1)) * (SIZE - 24)) if demo else 10 + (t * 7) % 20
    image[row : row + 12, 20 + 10 * camera : 32 + 10 * camera] = (230, 220, 40)
    return image


def write(path: Path, *, demos: int, length: int) -> Path:
    with h5py.File(path, "w") as handle:
        data = handle.create_group("data")
        data.attrs["env_args"] = json.dumps(
            {"env_name": "Lift", "type": 1, "env_kwargs": {"control_freq": 20}}
        )
        for demo in range(demos):
            group = data.create_group(f"demo_{demo}")
            group.create_dataset("actions", data=np.zeros((length, 7)))
            group.create_dataset("dones", data=np.zeros(length, np.int64))
            obs = group.create_group("obs")
            for c, camera in enumerate(CAMERAS):
                dataset = obs.create_dataset(
                    camera, (length, SIZE, SIZE, 3), np.uint8, chunks=(1, SIZE, SIZE, 3), compression="gzip"
                )
                for t in range(length):  # written a frame at a time, as a recorder does
                    dataset[t] = frame(demo, c, t, length)
    return path


MEASURE = """
import resource, sys
from rfr_viz.cli.app import app
try:
    app(sys.argv[1:], standalone_mode=True)
except SystemExit as end:
    code = end.code
print("PEAK_RSS_KB", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)
"""


READ = """
import resource, sys
from robofailring import load_dataset
(trajectory,) = load_dataset(sys.argv[1]).episodes
total = sum(int(frame.load()[0, 0, 0]) for frames in trajectory.views.values() for frame in frames)
print("PEAK_RSS_KB", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)
"""


H5PY = """
import resource, sys
import h5py
with h5py.File(sys.argv[1], "r") as handle:
    cameras = handle["data/demo_0/obs"]
    total = sum(int(cameras[name][t][0, 0, 0]) for name in cameras for t in range(len(cameras[name])))
print("PEAK_RSS_KB", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)
"""


def run(arguments: list[str], script: str = MEASURE) -> int:
    done = subprocess.run([sys.executable, "-c", script, *arguments], capture_output=True, text=True)
    peak = [line for line in done.stderr.splitlines() if line.startswith("PEAK_RSS_KB")]
    if done.returncode != 0 and not peak:
        raise SystemExit(f"{' '.join(arguments)} failed:\n{done.stderr}")
    return int(peak[-1].split()[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--lengths", type=int, nargs="+", default=list(LENGTHS), help="frames per demo")
    parser.add_argument("--codec", default="auto", help="the replay's --camera-codec (jpeg, av1, h264, auto)")
    options = parser.parse_args()
    print_machine()
    lengths: list[int] = options.lengths
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        source = write(tmp / "memory.hdf5", demos=2, length=20)
        labels = tmp / "labels.csv"
        labels.write_text("episode,outcome,symbol\ndemo_0,failure,grasp_wp2\ndemo_1,success,\n")
        memory, cache = tmp / "memory", ["--cache-dir", str(tmp / "cache")]
        subprocess.run(
            [sys.executable, "-m", "rfr_viz.cli.app", "build-memory", str(source), "--out", str(memory),
             "--labels", str(labels), *cache],
            check=True, capture_output=True,
        )  # fmt: skip
        # fits the memory's map once (cached beside it) and fills the embedding cache, as a user's first replay would
        codec = ["--camera-codec", options.codec]
        run(["replay", str(source), "--memory", str(memory), "--out", str(tmp / "warm"), *cache, *codec])
        peaks: dict[str, dict[int, int]] = {"h5py": {}, "read": {}, "detect": {}, "replay": {}}
        for length in lengths:
            path = write(tmp / f"demo_{length}.hdf5", demos=1, length=length)
            size = path.stat().st_size / 1e6
            raw = 3 * length * SIZE * SIZE * 3 / 1e6
            peaks["h5py"][length] = run([str(path)], H5PY)
            peaks["read"][length] = run([str(path)], READ)
            target = [str(path), "--memory", str(memory), "--trajectory", "demo_0", *cache]
            peaks["detect"][length] = run(["detect", *target])
            peaks["replay"][length] = run(["replay", *target, "--out", str(tmp / f"rec_{length}"), *codec])
            print(f"{length:>5} frames × 3 cameras: file {size:6.1f} MB (raw pixels {raw:6.1f} MB), peak RSS: "
                  + ", ".join(f"{job} {peaks[job][length] / 1024:6.1f} MiB" for job in peaks))  # fmt: skip
        for short, long in itertools.pairwise(lengths):
            print(f"growth {short} → {long} frames: "
                  + ", ".join(f"{job} {(peaks[job][long] - peaks[job][short]) / 1024:+.1f} MiB" for job in peaks))  # fmt: skip


if __name__ == "__main__":
    main()
