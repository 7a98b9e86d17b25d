"""What a dense failure memory costs beside the paper's: its entries, its build, its memory map, a replay.

Run: .venv/bin/python -m bench.bench_dense_memory [--data DIR] [--encoder SPEC] [--repeat 3]

The memory holds every failure episode of the set (the demo's simulated set by default, as the other
map benches), without success runs, built once as `end` (the paper's: one (I_0 ‖ I_end) entry per
failure view) and once as `dense` (from each failure's onset on, thinned at the default step). Per
kind: entries (and per view), the build's time (embeddings cached by a first build, so this is
decoding, hashing and pairing), the memory map's first fit in a fresh interpreter as a replay does it
(`rfr_viz.panels.umap.fit_map`: import, then one map per view; median of `--repeat`), its failure-type
purity (share of an entry's 5 nearest map neighbours with its type, within its view's map), and one
replay of a failure run against the memory with its own episode left out (scoring and recording, the
map already fitted): time and `.rrd` size.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from bench._sim_memories import default_data, in_fresh_process
from bench._timing import print_machine
from robofailring.data.layouts import load_dataset
from robofailring.detection.detector import FailureDetector
from robofailring.encoders import open_encoder
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import MemoryRecipe

KINDS = ("end", "dense")


def _child(memory_dir: Path) -> None:
    """Runs in a fresh interpreter: the import and the first fit of a memory's maps, as a replay's."""
    start = time.perf_counter()
    from rfr_viz.panels.umap import fit_map

    memory = FailureMemory.load(memory_dir)
    loaded = time.perf_counter()
    mapped = fit_map(memory)
    fitted = time.perf_counter()
    from rfr_viz.panels.map import class_id
    from rfr_viz.panels.umap_layout import knn_purity

    types = np.asarray([class_id(entry.symbol, entry.vocabulary) for entry in memory.entries])
    parts = [
        (knn_purity(mapped.maps[v].embedding, types[mapped.rows[v]]), len(mapped.rows[v]))
        for v in mapped.views
    ]
    purity = sum(value * count for value, count in parts) / sum(count for _, count in parts)
    print(json.dumps({"import": loaded - start, "fit": fitted - loaded, "purity": purity}))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--data", type=Path, default=None, help="dataset root (default: the demo's simulated set)"
    )
    parser.add_argument("--encoder", default="pixels", help="encoder spec")
    parser.add_argument("--repeat", type=int, default=3, help="fresh processes per map fit (medians)")
    parser.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.child)
        return
    print_machine()
    from rfr_viz.panels.umap import memory_map
    from rfr_viz.recordings.replay import record_replay

    data = args.data or default_data()
    encoder = open_encoder(args.encoder)
    trajectories = list(load_dataset(data))
    failures = [t for t in trajectories if t.is_failure]
    provenance = Provenance(data=data, encoder=args.encoder)
    print(f"data: {data} ({len(failures)} failure runs, {failures[0].length} frames each)")
    print(
        "| memory | entries | per view (mean) | frames offered per view (mean) | build s | first map fit s (import s) | type purity, map "
        "| replay s | replay .rrd MB |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    build_memories(
        failures, encoder, provenance=provenance, successes=False, recipe=MemoryRecipe(failure_frames="dense")
    )  # warm
    with tempfile.TemporaryDirectory() as folder:
        for kind in KINDS:
            start = time.perf_counter()
            memory, stats = build_memories(
                failures,
                encoder,
                provenance=provenance,
                successes=False,
                recipe=MemoryRecipe(failure_frames=kind),
            )
            built = time.perf_counter() - start
            saved = memory.save(Path(folder) / kind)
            fits = [in_fresh_process(__file__, str(saved)) for _ in range(args.repeat)]
            fit = statistics.median(run["fit"] for run in fits)
            imported = statistics.median(run["import"] for run in fits)
            views = Counter((e.episode, e.view) for e in memory.entries)
            trajectory = failures[0]
            mapped = memory_map(memory, directory=saved)  # fitted here, not timed with the replay
            start = time.perf_counter()
            trace = FailureDetector(memory, encoder).run(trajectory, leave_one_out=True)
            recording = record_replay(trajectory, trace, out=Path(folder) / f"{kind}.rrd", memory_map=mapped)
            replayed = time.perf_counter() - start
            print(
                f"| {kind} | {len(memory):,} | {np.mean(list(views.values())):.1f} "
                f"| {stats.offered / stats.views:.1f} | {built:.1f} "
                f"| {fit:.1f} ({imported:.1f}) | {fits[0]['purity']:.3f} | {replayed:.1f} "
                f"| {recording.stat().st_size / 1e6:.2f} |"
            )


if __name__ == "__main__":
    main()
