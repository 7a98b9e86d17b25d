"""What a content-keyed embedding cache costs (issue 13): hashing an image's bytes against decoding it.

The cache keys each frame by a digest of its file bytes, read on every lookup, so an image
rewritten with the same size and modification time is never served a stale embedding. This
prints, per image size and format, the per-frame time of: a `stat` (the old size + mtime key),
reading + hashing the bytes (the key now), reading + decoding the image (the least a cache miss
costs before encoding), and a full cached lookup of a warm cache.

Run: .venv/bin/python -m bench.bench_cache
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from bench._scenes import scene
from bench._timing import median_ms, print_machine
from robofailring.data.images import content_digest, read_image
from robofailring.data.model import Frame
from robofailring.encoders import CachedEncoder, load_encoder

FRAMES = 50
SIZES = ((128, 128), (256, 256), (480, 640))


def measure(paths: list[Path], frames: list[Frame], cached: CachedEncoder) -> tuple[float, ...]:
    """Per-frame ms of: stat, read + hash, read + decode, a warm cached lookup."""
    return (
        median_ms(lambda: [p.stat() for p in paths], 5) / FRAMES,
        median_ms(lambda: [content_digest(p.read_bytes()) for p in paths], 5) / FRAMES,
        median_ms(lambda: [read_image(p) for p in paths], 5) / FRAMES,
        median_ms(lambda: cached.encode_frames(frames), 5) / FRAMES,
    )


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    print_machine()
    import cv2

    encoder = load_encoder("pixels")
    print(f"per frame, median over {FRAMES} files (ms); hash = blake2b-128 of the file bytes")
    print(
        f"{'image':>14} {'format':>6} {'KiB':>6} {'stat':>7} {'read+hash':>10} {'read+decode':>12} "
        f"{'hash/decode':>12} {'warm lookup':>12}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for height, width in SIZES:
            for suffix in (".png", ".jpg"):
                folder = Path(tmp) / f"{height}x{width}{suffix}"
                folder.mkdir()
                paths = []
                for i in range(FRAMES):
                    path = folder / f"{i}{suffix}"
                    cv2.imwrite(str(path), scene(height, width, i)[:, :, ::-1])
                    paths.append(path)
                frames = [Frame(path=p) for p in paths]
                cached = CachedEncoder(encoder, cache_dir=Path(tmp) / "cache")
                cached.encode_frames(frames)  # warm the cache

                stat, hashed, decoded, lookup = measure(paths, frames, cached)
                size = sum(p.stat().st_size for p in paths) / FRAMES / 1024
                print(
                    f"{f'{height}x{width}':>14} {suffix[1:]:>6} {size:6.0f} {stat:7.3f} {hashed:10.3f} "
                    f"{decoded:12.3f} {hashed / decoded:11.0%} {lookup:12.3f}"
                )


if __name__ == "__main__":
    main()
