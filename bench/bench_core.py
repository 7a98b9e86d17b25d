"""Core speed figures (issue 2): search latency, detector overhead, encoder overhead, cache speed-up.

Run: .venv/bin/python -m bench.bench_core   (prints one line per figure, ratios measured side by side)
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from bench._timing import median_ms, print_machine
from robofailring import CachedEncoder, FailureDetector, FailureMemory, Frame, load_encoder
from robofailring.data.images import write_png
from robofailring.memory.failure import MemoryEntry
from robofailring.memory.pairs import pair_vectors


def synthetic_memory(
    trajectories: int = 50_000, views: int = 3, tasks: int = 80, half: int = 512
) -> FailureMemory:
    rng = np.random.default_rng(0)
    count = trajectories * views
    vectors = pair_vectors(
        rng.standard_normal((count, half), np.float32),
        rng.standard_normal((count, half), np.float32),
        pairing="concat",
    )
    entries = [
        MemoryEntry(
            task=f"task_{(i // views) % tasks}",
            symbol="slip_wp3",
            episode=f"ep{i // views}",
            view=("front", "overhead", "wrist")[i % views],
            start="s.png",
            end="e.png",
        )
        for i in range(count)
    ]
    return FailureMemory(vectors, entries, encoder="bench-random-512")


class TableEncoder:
    """Returns a fixed embedding: stands in for the forward pass so only detector overhead is timed."""

    identity = "bench-random-512"
    dim = 512

    def __init__(self) -> None:
        self.vector = np.ones((1, 512), np.float32) / np.sqrt(512)

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        return np.repeat(self.vector, len(images), axis=0)


def bench_search(memory: FailureMemory) -> None:
    rng = np.random.default_rng(1)
    queries = pair_vectors(rng.standard_normal((200, 512)), rng.standard_normal((200, 512)), pairing="concat")
    tasks = [f"task_{i % 80}" for i in range(200)]
    times = []
    for query, task in zip(queries, tasks, strict=True):
        start = time.perf_counter()
        memory.search(query, task, 5)
        times.append((time.perf_counter() - start) * 1000)
    print(
        f"search: {len(memory):,} entries, {len(memory.tasks)} tasks, 1024-d: median {statistics.median(times):.3f} ms"
        f" per query (target <= 0.5 ms); p95 {np.percentile(times, 95):.3f} ms"
    )


def bench_detector_overhead(memory: FailureMemory) -> None:
    detector = FailureDetector(memory, TableEncoder(), delta=0.92, k=5)
    session = detector.session("task_7")
    frames = {v: np.zeros((128, 128, 3), np.uint8) for v in ("front", "overhead", "wrist")}
    encoder = TableEncoder()
    step_ms = median_ms(lambda: session.step(frames), 300)
    encode_ms = median_ms(lambda: encoder.encode(list(frames.values())), 300)
    print(
        f"detector step, 3 views, excluding the encoder's forward pass: {step_ms - encode_ms:.3f} ms per frame "
        f"(target <= 1 ms)"
    )


def bench_encoder_overhead(images: list[np.ndarray]) -> None:
    import open_clip
    import torch
    from PIL import Image

    torch.manual_seed(0)
    model = open_clip.create_model("ViT-B-32", pretrained=None)
    with tempfile.TemporaryDirectory() as folder:
        checkpoint = Path(folder) / "vit-b-32-random.pt"
        torch.save(model.state_dict(), checkpoint)
        encoder = load_encoder(f"open_clip:ViT-B-32:{checkpoint}")
    clip_model, preprocess = encoder.model, encoder.preprocess  # type: ignore[attr-defined]

    def direct() -> None:
        with torch.inference_mode():
            batch = torch.stack([preprocess(Image.fromarray(image)) for image in images])
            clip_model.encode_image(batch)

    ours_ms, direct_ms = [], []
    for _ in range(3):  # interleaved, so both see the same machine state
        ours_ms.append(median_ms(lambda: encoder.encode(images), 1))
        direct_ms.append(median_ms(direct, 1))
    ratio = statistics.median(ours_ms) / statistics.median(direct_ms)
    print(
        f"ViT-B/32 batch of {len(images)}: project encoder {statistics.median(ours_ms):.0f} ms, "
        f"open_clip encode_image {statistics.median(direct_ms):.0f} ms -> ratio {ratio:.3f} (target <= 1.10)"
    )
    return None


def bench_cache(paths: list[Path], spec: str, encoder_factory: Callable[[], object]) -> None:
    frames = [Frame(path=p) for p in paths]
    with tempfile.TemporaryDirectory() as cache:
        encoder = CachedEncoder(encoder_factory(), cache_dir=Path(cache))  # type: ignore[arg-type]
        first = median_ms(lambda: encoder.encode_frames(frames), 1)
        second = median_ms(
            lambda: CachedEncoder(encoder.encoder, cache_dir=Path(cache)).encode_frames(frames), 1
        )
    print(
        f"embedding cache, {spec}, {len(frames)} frames: first pass {first:.0f} ms, second {second:.1f} ms -> "
        f"{first / second:.1f}x faster (target >= 10x)"
    )


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    print_machine()
    memory = synthetic_memory()
    bench_search(memory)
    bench_detector_overhead(memory)
    rng = np.random.default_rng(2)
    images = [rng.integers(0, 255, (128, 128, 3), dtype=np.uint8) for _ in range(32)]
    with tempfile.TemporaryDirectory() as folder:
        paths = []
        for i in range(300):
            path = Path(folder) / f"{i}.png"
            write_png(path, np.roll(images[i % 32], i, axis=1))
            paths.append(path)
        bench_cache(paths, "pixels", lambda: load_encoder("pixels"))
        bench_encoder_overhead(images)

        import open_clip
        import torch

        torch.manual_seed(0)
        checkpoint = Path(folder) / "vit.pt"
        torch.save(open_clip.create_model("ViT-B-32", pretrained=None).state_dict(), checkpoint)
        bench_cache(paths[:96], "ViT-B/32", lambda: load_encoder(f"open_clip:ViT-B-32:{checkpoint}"))


if __name__ == "__main__":
    main()
