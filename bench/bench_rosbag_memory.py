"""Peak resident memory replaying a 200- and a 2,000-message ROS bag (issue 23): it must not grow with length.

Run: .venv/bin/python -m bench.bench_rosbag_memory [--kind mcap|sqlite3|ros1] [--size 96] [--lengths 200,2000,4000]
     [--codec av1]

Bags are written with rosbags' own writer (one `rgb8` topic, `--size` px). A memory of three short
failure bags is built once with the `pixels` encoder. Each measurement runs in a fresh subprocess,
which reports its own peak RSS (`resource.getrusage(RUSAGE_SELF).ru_maxrss`):
  read:   open the bag and decode every frame once (the layout's reader alone);
  replay: `robofailring replay FOLDER --memory M --out DIR` on a folder holding the one bag (reader,
          detector and recording together).
Every replay uses one camera codec (`--codec`, default av1): `auto` would pick JPEG for the short
bag and AV1 for the long one, and the AV1 encoder's own ~35 MiB would read as growth with length.
The bag's size on disk is printed beside them: a reader that kept the messages would grow by it.
Control: the same frames as a folder of PNG files (`<episode>/<view>/<n>.png`) replayed the same way,
so what the replay itself keeps per frame (scores, the recording) is told apart from the bag reader.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "tests"), str(HERE.parent / "src"), str(HERE.parent)]


def _frames(size: int) -> Callable[[int, int], np.ndarray]:
    """A rosbag_writer FrameFn: the synthetic scene, looping every 50 frames."""
    from synthetic import synthetic_frame

    return lambda view, t: synthetic_frame("pick_cube", None, view, t % 50, 50, size=size)


def _child(mode: str, bag: str, memory: str, out: str, cache: str, codec: str) -> None:
    """Run one measurement in this process and print its peak RSS (MiB) as JSON."""
    if mode == "read":
        from robofailring import load_trajectory

        trajectory = load_trajectory(Path(bag), task="pick_cube")
        frames = next(iter(trajectory.views.values()))
        total = sum(int(frame.load()[0, 0, 0]) for frame in frames)
        assert total >= 0 and len(frames) == trajectory.length
    else:
        from rfr_viz.cli.app import app

        try:
            app([
                "replay", bag, "--memory", memory, "--out", out, "--cache-dir", cache, "--task", "pick_cube",
                "--camera-codec", codec,
            ])  # fmt: skip
        except SystemExit as done:
            if done.code not in (0, None):
                raise
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    print(json.dumps({"peak_mib": peak_kib / 1024}))


def _measure(mode: str, bag: Path, memory: Path, work: Path, codec: str) -> float:
    out, cache = work / f"rec-{mode}-{bag.name}", work / "cache"  # `bag`: a folder holding one episode
    command = [sys.executable, __file__, "--child", mode, str(bag), str(memory), str(out), str(cache), codec]
    env = {**os.environ, "ROBOFAILRING_PROGRESS": "0", "PYTHONPATH": os.pathsep.join(sys.path[:3])}
    done = subprocess.run(command, capture_output=True, text=True, env=env, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{mode} of {bag} failed:\n{done.stdout}\n{done.stderr}")
    return float(json.loads(done.stdout.strip().splitlines()[-1])["peak_mib"])


def _size_mib(path: Path) -> float:
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    return sum(p.stat().st_size for p in files) / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--kind", default="mcap", choices=("mcap", "sqlite3", "ros1"))
    parser.add_argument("--size", type=int, default=96, help="image side in pixels")
    parser.add_argument("--lengths", default="200,2000,4000", help="messages per bag, comma-separated")
    parser.add_argument("--codec", default="av1", help="every replay's --camera-codec (jpeg, av1, h264)")
    args = parser.parse_args()
    from rosbag_writer import write_bag

    from bench._timing import print_machine
    from robofailring.data.images import write_png

    print_machine()

    lengths = [int(n) for n in args.lengths.split(",")]
    topics = (("/cam_front/image_raw", "rgb8"),)
    suffix = ".bag" if args.kind == "ros1" else ""
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        failures = work / "failures"
        for number in range(3):
            write_bag(
                failures / f"fail_{number}{suffix}",
                kind=args.kind,
                topics=topics,
                frames=_frames(args.size),
                count=20,
            )
        labels = work / "labels.csv"
        labels.write_text(
            "episode,outcome,symbol\n" + "".join(f"fail_{n},failure,grasp_wp2\n" for n in range(3))
        )
        memory = work / "memory"
        env = {**os.environ, "ROBOFAILRING_PROGRESS": "0", "PYTHONPATH": os.pathsep.join(sys.path[:3])}
        subprocess.run(
            [sys.executable, "-m", "rfr_viz.cli.app", "build-memory", str(failures), "--labels", str(labels),
             "--task", "pick_cube", "--out", str(memory), "--cache-dir", str(work / "cache")],
            check=True, env=env, capture_output=True,
        )  # fmt: skip
        print(
            f"ROS bag peak RSS ({args.kind}, one rgb8 topic, {args.size}×{args.size} px, {args.codec} camera; "
            "fresh process each)"
        )
        print(f"{'messages':>9} {'bag MiB':>8} {'read MiB':>9} {'replay MiB':>11} {'PNG replay MiB':>15}")
        for length in lengths:
            bag = write_bag(
                work / f"bags_{length}" / f"run_{length}{suffix}",
                kind=args.kind,
                topics=topics,
                frames=_frames(args.size),
                count=length,
            )
            read = _measure(
                "read", bag.parent, memory, work, args.codec
            )  # a folder of one bag (a .bag file too)
            replay = _measure("replay", bag.parent, memory, work, args.codec)
            folder = work / "png" / f"run_{length}" / "front"
            folder.mkdir(parents=True)
            for t in range(length):
                write_png(folder / f"{t}.png", _frames(args.size)(0, t))
            control = _measure("replay", folder.parent, memory, work, args.codec)
            print(f"{length:>9} {_size_mib(bag):>8.1f} {read:>9.1f} {replay:>11.1f} {control:>15.1f}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        _child(*sys.argv[2:8])
    else:
        main()
