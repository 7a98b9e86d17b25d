"""Does the memory map answer "which failures look alike"? Failure-type purity of the map before and now.

Run: .venv/bin/python -m bench.bench_memory_map [--data DIR]... [--encoder SPEC]... [--k 5]

Before: one UMAP of every memory vector (the pair vectors norm([f(I_start) ‖ f(I_end)])), as rfr_viz drew
it. Now (`rfr_viz.panels.umap`): one map per camera view of what changed, norm(f(I_end) − f(I_start)),
with each task's mean change in that view removed. The memory holds every failure episode of the set
(the demo's simulated set by default). Columns: the share of an entry's k nearest map neighbours with
its failure type (now: within its view's map; chance = Σ p²), the same for the vectors the map was
fitted on (cosine), the silhouette of the map by failure type, and the purity by view and by task,
which is what the map clustered instead.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from sklearn.metrics import silhouette_score

from bench._sim_memories import chance_purity, default_data, default_encoders, failure_memory
from bench._timing import print_machine
from rfr_viz.panels.umap import fit_map
from rfr_viz.panels.umap_layout import fit_map_2d, knn_purity


def _cosine_purity(vectors: np.ndarray, labels: np.ndarray, k: int) -> float:
    units = vectors / np.maximum(np.linalg.norm(vectors, axis=1, keepdims=True), 1e-12)
    similarity = units @ units.T
    np.fill_diagonal(similarity, -np.inf)
    nearest = np.argsort(-similarity, axis=1)[:, :k]
    return float((labels[nearest] == labels[:, None]).mean())


def _weighted(parts: list[tuple[float, int]]) -> float:
    return sum(value * count for value, count in parts) / sum(count for _, count in parts)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--data", type=Path, action="append", default=None, help="dataset root (repeatable)")
    parser.add_argument("--encoder", action="append", default=None, help="encoder spec (repeatable)")
    parser.add_argument("--k", type=int, default=5, help="map neighbours per entry")
    args = parser.parse_args()
    print_machine()
    k = args.k
    print(
        f"| data | encoder | entries | layout | type purity, map (k={k}) | type purity, fitted vectors "
        "| silhouette by type | view purity | task purity | chance |"
    )
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for data in args.data or [default_data()]:
        for spec in args.encoder or default_encoders():
            labelled = failure_memory(data, spec)
            memory, types, views = labelled.memory, labelled.failure_types, labelled.views
            tasks = np.asarray([entry.task for entry in memory.entries])
            before = fit_map_2d(memory.vectors).embedding
            now = fit_map(memory)
            per_view = [(view, now.rows[view], now.maps[view]) for view in now.views]
            rows = {
                "one map of the vectors (before)": (
                    knn_purity(before, types, k=k),
                    _cosine_purity(memory.vectors, types, k),
                    silhouette_score(before, types),
                    f"{knn_purity(before, views, k=k):.3f}",
                    knn_purity(before, tasks, k=k),
                ),
                "per view, change, task mean removed (now)": (
                    _weighted([(knn_purity(m.embedding, types[r], k=k), len(r)) for _, r, m in per_view]),
                    _weighted([(_cosine_purity(m.vectors, types[r], k), len(r)) for _, r, m in per_view]),
                    _weighted([(silhouette_score(m.embedding, types[r]), len(r)) for _, r, m in per_view]),
                    "one map each",
                    _weighted([(knn_purity(m.embedding, tasks[r], k=k), len(r)) for _, r, m in per_view]),
                ),
            }
            name = f"{data.name} ({len({e.episode for e in memory.entries})} failures)"
            for layout, (purity, fitted, silhouette, view_purity, task_purity) in rows.items():
                print(
                    f"| {name} | {spec.split(':')[0]} | {len(types)} | {layout} | {purity:.3f} | {fitted:.3f} "
                    f"| {silhouette:+.3f} | {view_purity} | {task_purity:.3f} | {chance_purity(types):.3f} |"
                )


if __name__ == "__main__":
    main()
