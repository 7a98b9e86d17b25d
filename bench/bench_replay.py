"""Replay figures (issue 4): recording speed, recording size against its JPEGs, UMAP fit and cache.

Run: .venv/bin/python -m bench.bench_replay   (one line per figure, measured side by side in one run)
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow.compute as pc
from rerun.chunk import RrdReader

from bench._timing import print_machine
from rfr_viz.panels.umap import CACHE_FILE, memory_map
from rfr_viz.paths import CAMERA_ROOT, DetectorPaths
from rfr_viz.recordings.replay import record_replay
from robofailring import (
    CachedEncoder,
    FailureDetector,
    FailureMemory,
    load_dataset,
    load_encoder,
    load_trajectory,
)
from robofailring.data.images import write_png
from robofailring.memory.failure import MemoryEntry
from robofailring.memory.pairs import pair_vectors

VIEWS = ("front", "overhead", "wrist")
REPLAY = DetectorPaths()  # a replay's entities (no encoder prefix)
SIZE = 128
LENGTH = 100
TASK = "pick_cube"
SYMBOLS = ("grasp_wp2", "rotation_x_wp1", "slip_wp3", "translation_y_wp2", "wrong_object")


def scene(symbol: str | None, view: int, t: int, length: int, rng: np.random.Generator) -> np.ndarray:
    """A 128 px tabletop-like frame: shaded background, a table edge, an object and a gripper, sensor noise."""
    rows = np.linspace(0.55, 1.0, SIZE, dtype=np.float32)[:, None, None]
    image = np.broadcast_to(np.array([70, 95, 140], np.float32) * rows, (SIZE, SIZE, 3)).copy()
    image[SIZE * 2 // 3 :] = (120 + 10 * view, 100, 80)
    progress = t / max(length - 1, 1)
    drift = 0 if symbol is None else (sum(map(ord, symbol)) % 7 + 3) * 4
    top = int(20 + progress * 50)
    left = int(20 + view * 18 + progress * drift)
    image[top : top + 22, left : left + 22] = (230, 210, 50)
    image[top - 18 : top - 4, left + 6 : left + 16] = (200, 200, 210)
    image += rng.normal(0.0, 4.0, image.shape).astype(np.float32)
    return np.clip(image, 0, 255).astype(np.uint8)


def write_dataset(root: Path) -> Path:
    """AHA-layout failures of one task (the memory) at 128 px."""
    rng = np.random.default_rng(0)
    for symbol in SYMBOLS:
        for episode in range(3):
            folder = root / f"{TASK}_{symbol}_episode{episode}"
            folder.mkdir(parents=True)
            for v, view in enumerate(VIEWS):
                for t in range(12):
                    write_png(folder / f"{view}_{t}.png", scene(symbol, v, t + episode, 14, rng))
    return root


def write_trajectory(folder: Path) -> Path:
    rng = np.random.default_rng(1)
    for v, view in enumerate(VIEWS):
        (folder / view).mkdir(parents=True)
        for t in range(LENGTH):
            write_png(folder / view / f"{t}.png", scene("grasp_wp2", v, t, LENGTH, rng))
    return folder


def jpeg_bytes(recording: Path) -> tuple[int, int]:
    """Bytes of the JPEG blobs held by a recording (cameras, neighbours), read back from the file."""
    totals = {}
    for root in (f"{CAMERA_ROOT}/**", f"{REPLAY.neighbors_root}/**"):
        total = 0
        for chunk in RrdReader(recording).stream().filter(content=root).to_chunks():
            batch = chunk.to_record_batch()
            if "EncodedImage:blob" in batch.schema.names:
                blobs = batch.column("EncodedImage:blob").flatten()  # one blob per row
                total += int(pc.sum(pc.list_value_length(blobs)).as_py() or 0)
        totals[root] = total
    return totals[f"{CAMERA_ROOT}/**"], totals[f"{REPLAY.neighbors_root}/**"]


def bench_replay(folder: Path) -> None:
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=folder / "cache")
    memory, _ = FailureMemory.build(load_dataset(write_dataset(folder / "data")), encoder)
    memory.save(folder / "memory")
    trajectory = load_trajectory(write_trajectory(folder / "episode"), task=TASK)
    detector = FailureDetector(memory, encoder, delta=0.95, k=5)
    detector.run(trajectory)  # fills the embedding cache
    mapped = memory_map(memory, directory=folder / "memory")  # fits and caches the map once
    frames = LENGTH
    detect_s, record_s, total_s = [], [], []
    for repeat in range(3):
        start = time.perf_counter()
        trace = detector.run(trajectory)
        middle = time.perf_counter()
        mapped = memory_map(memory, directory=folder / "memory")
        out = record_replay(trajectory, trace, out=folder / f"replay{repeat}.rrd", memory_map=mapped)
        end = time.perf_counter()
        detect_s.append(middle - start)
        record_s.append(end - middle)
        total_s.append(end - start)
    total = statistics.median(total_s)
    print(
        f"(a) replay of a {len(VIEWS)}-view, {frames}-frame, {SIZE} px trajectory, embeddings cached: "
        f"{frames / total:.0f} frames/s end to end (detector {statistics.median(detect_s) * 1000:.0f} ms + "
        f"recording {statistics.median(record_s) * 1000:.0f} ms for {frames} frames; target >= 100 frames/s); "
        f"t_det = {trace.t_det}, {len(memory)} memory entries"
    )
    cameras, neighbors = jpeg_bytes(out)
    size = out.stat().st_size
    print(
        f"(b) recording {size / 1e3:.0f} kB / JPEG images it holds {(cameras + neighbors) / 1e3:.0f} kB "
        f"(cameras {cameras / 1e3:.0f} kB + neighbour images {neighbors / 1e3:.0f} kB) = "
        f"{size / (cameras + neighbors):.3f} (target <= 1.3)"
    )


def clustered_memory(count: int = 15_000, *, clusters: int = 7, half: int = 512) -> FailureMemory:
    """Random-ish 1024-d memory vectors around a few cluster centres, one per failure type."""
    rng = np.random.default_rng(3)
    kinds = (
        "rotation_x_wp1",
        "translation_y_wp2",
        "grasp_wp2",
        "slip_wp3",
        "no_rotation_wp2",
        "wrong_sequence_wp3",
        "wrong_object",
    )
    labels = rng.integers(0, clusters, count)
    centres_start = rng.standard_normal((clusters, half)).astype(np.float32)
    centres_end = rng.standard_normal((clusters, half)).astype(np.float32)
    noise = lambda: rng.standard_normal((count, half)).astype(np.float32)  # noqa: E731
    vectors = pair_vectors(
        centres_start[labels] + 0.9 * noise(), centres_end[labels] + 0.9 * noise(), pairing="concat"
    )
    entries = [
        MemoryEntry(
            task=f"task_{i % 40}",
            symbol=kinds[label % len(kinds)],
            episode=f"episode{i // 3}",
            view=VIEWS[i % 3],
            start="start.png",
            end="end.png",
        )
        for i, label in enumerate(labels)
    ]
    return FailureMemory(vectors, entries, encoder="bench-random-512")


class RandomEncoder:
    """Stands in for the encoder of the random 15,000-entry memory (same identity, unit vectors)."""

    identity = "bench-random-512"
    dim = 512

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        rng = np.random.default_rng(len(images))
        vectors = rng.standard_normal((len(images), self.dim)).astype(np.float32)
        return vectors / np.linalg.norm(vectors, axis=1, keepdims=True)


def bench_umap(folder: Path) -> FailureMemory:
    memory = clustered_memory()
    directory = folder / "memory-15k"
    directory.mkdir()
    start = time.perf_counter()
    first = memory_map(memory, directory=directory)
    fit_s = time.perf_counter() - start
    start = time.perf_counter()
    second = memory_map(memory, directory=directory)
    cached_s = time.perf_counter() - start
    assert first.fitted and not second.fitted and first.views == second.views
    assert all(np.array_equal(first.maps[v].embedding, second.maps[v].embedding) for v in first.views)
    rng = np.random.default_rng(4)
    queries = memory.vectors[rng.choice(len(memory), 100)]
    start = time.perf_counter()
    for view in first.views:  # one map per view: a frame's 3 views are placed in their own maps
        first.project(view, "task_0", queries)
    project_ms = (time.perf_counter() - start) * 1000
    print(
        f"(c) memory map of {len(memory):,} entries ({memory.dim}-d): UMAP fit {fit_s:.1f} s (target <= 60 s, "
        f"includes numba compilation), second replay {cached_s * 1000:.0f} ms from {CACHE_FILE} "
        f"({(directory / CACHE_FILE).stat().st_size / 1e3:.0f} kB, no UMAP work); placing 300 queries "
        f"(100 frames x 3 views, one map each) {project_ms:.0f} ms"
    )
    return memory


def bench_large_map_size(folder: Path, memory: FailureMemory) -> None:
    """(b) again, against the 15,000-entry memory: its map (positions, classes, hover labels) is in every file."""
    trajectory = load_trajectory(folder / "episode", task="task_0")
    trace = FailureDetector(memory, CachedEncoder(RandomEncoder(), enabled=False), delta=1.0, k=5).run(
        trajectory
    )  # type: ignore[arg-type]
    mapped = memory_map(memory, directory=folder / "memory-15k")
    out = record_replay(trajectory, trace, out=folder / "large.rrd", memory_map=mapped)
    cameras, neighbors = jpeg_bytes(out)
    size = out.stat().st_size
    map_bytes = sum(
        chunk.to_record_batch().nbytes
        for chunk in RrdReader(out).stream().filter(content=f"{REPLAY.map_root}/**").to_chunks()
    )
    print(
        f"(b') the same trajectory against the {len(memory):,}-entry memory: recording {size / 1e3:.0f} kB / "
        f"JPEG images {(cameras + neighbors) / 1e3:.0f} kB = {size / (cameras + neighbors):.3f}; the static map "
        f"of all entries holds {map_bytes / 1e3:.0f} kB (positions, classes, labels, legend), and "
        f"random queries change all {trace.k} neighbours at every frame"
    )


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    print_machine()
    with tempfile.TemporaryDirectory() as folder:
        large = bench_umap(Path(folder))  # first, so its time includes numba's one-off compilation
        bench_replay(Path(folder))
        bench_large_map_size(Path(folder), large)


if __name__ == "__main__":
    main()
