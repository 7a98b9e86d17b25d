"""Time the embedded default demo set: 4 tasks x 8 kinds x 2 episodes x 3 views, 40 frames, 128 px."""

from __future__ import annotations

import argparse
import collections
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from bench._timing import print_machine
from robofailring.sim import GenerateConfig, generate_dataset

TARGET_S = 180.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--out", type=Path, default=None, help="keep the dataset here (default: a temp dir)")
    parser.add_argument("--ood", action="store_true")
    args = parser.parse_args()
    print_machine()
    keep = args.out is not None
    root = Path(tempfile.mkdtemp(prefix="bench-generate-"))
    out = args.out if keep else root / "demo"
    config = GenerateConfig(out=out, workers=args.workers, ood=args.ood)
    if keep and out.exists():
        shutil.rmtree(out)  # time a full generation, not a cache hit
    done = 0

    def tick(n: int) -> None:
        nonlocal done
        done += n

    start = time.perf_counter()
    generate_dataset(config, progress=tick)
    elapsed = time.perf_counter() - start
    manifest = json.loads((out / "manifest.json").read_text())
    images = sum(len(r["views"]) * r["frames"] for r in manifest["episodes"])
    attempted: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0])
    for record in manifest["episodes"]:
        if record["perturbation"] is not None:
            family = record["kind"]
            attempted[family][0] += record["outcome"] == "failure"
            attempted[family][1] += 1
    print(f"episodes: {done}  images: {images}  workers: {args.workers}  cpus: {os.cpu_count()}")
    print(f"generate_dataset: {elapsed:.1f} s  ({elapsed / done:.2f} s/episode, target <= {TARGET_S:.0f} s)")
    print(f"ratio to target: {elapsed / TARGET_S:.2f}")
    print("attempted failures that failed, per family:")
    for family, (failed, total) in attempted.items():
        print(f"  {family:15s} {failed}/{total}")
    if not keep:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
