"""Frames per second encoded in this process against a local Ray cluster (`--ray`, docs/ray.md), in one run.

For each encoder (the weight-free `pixels`, a random-initialised open_clip ViT-B/32 checkpoint written
here) the same camera-like 480×640 PNG frames are encoded from a cold embedding cache twice: by
`CachedEncoder.encode_frames` here (decode + encode, batches of 64), and by `CachedEncoder.prefetch`
on a Ray cluster started in this process with `ray.init(num_cpus=CPUS)` (Ray Data: frames → an actor
pool that decodes and encodes, embeddings streamed back into the cache). The Ray figure counts the
whole pass (the actors starting and loading the encoder, the driver hashing the files and writing
the cache); the cluster's own start is printed apart. The ratio is Ray over local throughput.

On one machine Ray can only share the same cores (and pays for actors, serialisation and the
object store), so expect a ratio at or below 1 here; a cluster of N such nodes multiplies the
encoding throughput by about N while the driver's hashing and cache writes stay on one machine.

Run: .venv/bin/python -m bench.bench_ray [--frames 256] [--cpus 2]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bench._scenes import scene
from bench._timing import print_machine
from robofailring.data.images import write_png
from robofailring.data.model import Frame
from robofailring.encoders import open_encoder


def timed(run: Callable[[], object]) -> float:
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


def compare(label: str, spec: str, frames: list[Frame], folder: Path) -> None:
    """One encoder: frames/s here and on the cluster from cold caches, the ratio and the largest difference."""
    here = open_encoder(spec, device="cpu", cache_dir=folder / "cache-local")
    local_s = timed(lambda: here.encode_frames(frames))
    on_ray = open_encoder(spec, device="cpu", cache_dir=folder / "cache-ray", ray="auto")
    ray_s = timed(lambda: on_ray.prefetch(frames))
    again = open_encoder(spec, device="cpu", cache_dir=folder / "cache-ray-again", ray="auto")
    again_s = timed(lambda: again.prefetch(frames))  # Ray's worker processes already up
    difference = np.abs(on_ray.encode_frames(frames) - here.encode_frames(frames)).max()
    local_rate, ray_rate, again_rate = (len(frames) / s for s in (local_s, ray_s, again_s))
    print(
        f"{label:<20} {len(frames):>6} {local_rate:>10.1f} {ray_rate:>10.1f} {again_rate:>10.1f} "
        f"{ray_rate / local_rate:>8.2f} {again_rate / local_rate:>8.2f} {difference:>10.1e}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--frames", type=int, default=256, help="frames per encoder (pixels; ViT-B/32 a quarter)"
    )
    parser.add_argument("--cpus", type=int, default=2, help="CPUs of the local Ray cluster")
    args = parser.parse_args()
    print_machine()
    os.environ.setdefault("ROBOFAILRING_PROGRESS", "0")
    import open_clip
    import ray
    import torch

    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        frames = []
        for i in range(args.frames):
            write_png(folder / f"{i}.png", scene(480, 640, i))
            frames.append(Frame(path=folder / f"{i}.png"))
        torch.manual_seed(0)
        checkpoint = folder / "vit-b-32-random.pt"
        torch.save(open_clip.create_model("ViT-B-32", pretrained=None).state_dict(), checkpoint)
        start_s = timed(lambda: ray.init(num_cpus=args.cpus, include_dashboard=False, log_to_driver=False))
        print(f"local Ray cluster of {args.cpus} CPUs started in {start_s:.1f} s (not counted below)")
        print(
            f"{'encoder':<20} {'frames':>6} {'local f/s':>10} {'Ray f/s':>10} {'again f/s':>10} "
            f"{'ratio':>8} {'again':>8} {'max |diff|':>10}"
        )
        compare("pixels", "pixels", frames, folder / "pixels")
        compare(
            "open_clip ViT-B/32",
            f"open_clip:ViT-B-32:{checkpoint}",
            frames[: max(8, args.frames // 4)],
            folder / "vit",
        )
        ray.shutdown()


if __name__ == "__main__":
    main()
