"""Decoding speed of a LeRobot episode (issue 11): frames/s from AV1 video, sequential and with
`--stride 5`, against reading the same frames from PNG files.

Run: .venv/bin/python -m bench.bench_decode [--frames 150] [--size 256]
(writes a 3-camera LeRobot v3.0 dataset, AV1 via libsvtav1 with a keyframe every 2 frames as
lerobot 0.4 writes it, and the same frames as PNG, to a temporary folder; prints one line per figure)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bench._timing import print_machine

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from lerobot_writer import scene, write_lerobot_v3

import robofailring.data.video as video_module
from robofailring import load_dataset
from robofailring.data.images import read_image, write_png

CAMERAS = ("front", "top", "wrist")


def frame_fn(size: int) -> Callable[[int, int, int], np.ndarray]:
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 3.0, (8, size, size, 3)).astype(np.float32)

    def make(episode: int, camera: int, t: int) -> np.ndarray:
        base = scene(episode, camera, t, size).astype(np.float32) + noise[t % len(noise)]
        return np.clip(base, 0, 255).astype(np.uint8)

    return make


def frames_per_second(read: Callable[[int], object], indices: list[int]) -> float:
    start = time.perf_counter()
    for t in indices:
        read(t)
    return len(indices) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=150, help="frames per camera (one episode)")
    parser.add_argument("--size", type=int, default=256, help="square image size in pixels")
    args = parser.parse_args()
    print_machine(libraries=("av",))
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        make = frame_fn(args.size)
        write_lerobot_v3(
            root / "lerobot",
            lengths=(args.frames,),
            tasks=("pick",),
            cameras=CAMERAS,
            size=args.size,
            fps=30,
            frame=make,
        )
        for c, camera in enumerate(CAMERAS):
            (root / "png" / camera).mkdir(parents=True)
            for t in range(args.frames):
                write_png(root / "png" / camera / f"{t}.png", make(0, c, t))
        print(
            f"one episode, {len(CAMERAS)} cameras × {args.frames} frames of {args.size} px (AV1 g=2 vs PNG)"
        )
        for stride in (1, 5):
            indices = list(range(0, args.frames, stride))
            video_module._FILES.clear()  # fresh readers: nothing decoded before
            (trajectory,) = load_dataset(root / "lerobot")
            video_fps = frames_per_second(
                lambda t, views=trajectory.views: [views[camera][t].load() for camera in CAMERAS], indices
            ) * len(CAMERAS)
            png_fps = frames_per_second(
                lambda t: [read_image(root / "png" / camera / f"{t}.png") for camera in CAMERAS], indices
            ) * len(CAMERAS)
            label = "sequential" if stride == 1 else f"stride {stride}  "
            print(
                f"{label}: video {video_fps:8.1f} frames/s   PNG {png_fps:8.1f} frames/s   "
                f"video/PNG ratio {video_fps / png_fps:.2f}"
            )


if __name__ == "__main__":
    main()
