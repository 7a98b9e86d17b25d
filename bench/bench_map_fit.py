"""The first memory map of a fresh process: umap-learn's `UMAP.fit` against rfr_viz's fit, on the simulator's failures.

Run: .venv/bin/python -m bench.bench_map_fit [--data DIR] [--encoder SPEC]... [--repeat 3]

The map before: `umap.UMAP(metric="cosine", precomputed_knn=Faiss neighbours).fit_transform`, whose
fuzzy-graph code (numba, not cached) is compiled in every new process. The map now
(`rfr_viz.panels.umap_layout`): the same fuzzy simplicial set built in numpy, then umap-learn's
`simplicial_set_embedding` with UMAP's defaults. Each runs in its own fresh interpreter (as the first
replay of a session does), on the same vectors: `import umap` + Faiss, the first fit, a second fit in
the same process; the two alternate `--repeat` times and the medians are printed (on a shared machine
one run is noisy). Then each map's failure-type purity (share of a point's 5 nearest map neighbours
with its failure type; chance = Σ p²) and how far apart the two maps are.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from bench._sim_memories import (
    chance_purity,
    default_data,
    default_encoders,
    failure_memory,
    in_fresh_process,
)
from bench._timing import print_machine

VARIANTS = {"umap-learn UMAP.fit": "umap-learn", "rfr_viz (numpy graph)": "rfr_viz"}


def _child(variant: str, vectors_file: Path, out: Path) -> None:
    """Runs in a fresh interpreter: times the imports, a first and a second fit, and saves the map."""
    start = time.perf_counter()
    import faiss  # noqa: F401
    import umap  # noqa: F401

    imported = time.perf_counter()
    vectors = np.load(vectors_file)
    fit = _umap_learn if variant == "umap-learn" else _rfr_viz
    first = fit(vectors)
    fitted = time.perf_counter()
    fit(vectors)
    again = time.perf_counter()
    np.save(out, first)
    timings = {"import": imported - start, "first": fitted - imported, "second": again - fitted}
    print(json.dumps(timings))


def _rfr_viz(vectors: np.ndarray) -> np.ndarray:
    from rfr_viz.panels.umap_layout import fit_map_2d

    return fit_map_2d(vectors).embedding


def _umap_learn(vectors: np.ndarray) -> np.ndarray:
    """The map as rfr_viz made it before: umap-learn's UMAP on exact Faiss neighbours, scaled alike."""
    import warnings

    import faiss
    import umap

    from rfr_viz.panels.umap_layout import MIN_DIST, N_NEIGHBORS, SEED, scaled_to_unit_box

    n_neighbors = max(2, min(N_NEIGHBORS, len(vectors) - 1))
    index = faiss.IndexFlatIP(vectors.shape[1])
    index.add(vectors)
    similarities, ids = index.search(vectors, n_neighbors)
    distances = np.clip(1.0 - similarities, 0.0, 2.0).astype(np.float32)
    reducer = umap.UMAP(
        n_components=2,
        n_neighbors=n_neighbors,
        min_dist=MIN_DIST,
        metric="cosine",
        random_state=SEED,
        n_jobs=1,
        precomputed_knn=(ids, distances, None),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        embedding = np.asarray(reducer.fit_transform(vectors), dtype=np.float32)
    return scaled_to_unit_box(embedding)


def _run(variant: str, vectors_file: Path, out: Path) -> dict[str, float]:
    return in_fresh_process(__file__, variant, str(vectors_file), str(out))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--data", type=Path, default=None, help="dataset root (default: the demo's simulated set)"
    )
    parser.add_argument("--encoder", action="append", default=None, help="encoder spec (repeatable)")
    parser.add_argument("--repeat", type=int, default=3, help="fresh processes per variant (medians)")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.child[0], Path(args.child[1]), Path(args.child[2]))
        return
    print_machine()
    from rfr_viz.panels.umap_layout import knn_purity

    data = args.data or default_data()
    print(f"data: {data}")
    print(
        "| encoder | entries | map | import umap + faiss s | first fit s | second fit s | first map s "
        "| purity (type) | chance | max |Δ| to umap-learn's map |"
    )
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for spec in args.encoder or default_encoders():
        labelled = failure_memory(data, spec)
        types = labelled.failure_types
        with tempfile.TemporaryDirectory() as folder:
            vectors_file = Path(folder) / "vectors.npy"
            np.save(vectors_file, np.ascontiguousarray(labelled.memory.vectors, dtype=np.float32))
            runs: dict[str, list[dict[str, float]]] = {name: [] for name in VARIANTS}
            for _ in range(args.repeat):  # alternating, so both see the same load
                for name, variant in VARIANTS.items():
                    runs[name].append(_run(variant, vectors_file, Path(folder) / f"{variant}.npy"))
            maps = {name: np.load(Path(folder) / f"{variant}.npy") for name, variant in VARIANTS.items()}
            reference = maps[next(iter(VARIANTS))]
            for name, timings in runs.items():
                median = {key: statistics.median(run[key] for run in timings) for key in timings[0]}
                total = statistics.median(run["import"] + run["first"] for run in timings)
                print(
                    f"| {spec.split(':')[0]} | {len(types)} | {name} | {median['import']:.1f} | {median['first']:.1f} "
                    f"| {median['second']:.2f} | {total:.1f} "
                    f"| {knn_purity(maps[name], types):.3f} | {chance_purity(types):.3f} "
                    f"| {np.abs(maps[name] - reference).max():.2g} |"
                )


if __name__ == "__main__":
    main()
