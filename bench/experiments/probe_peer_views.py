"""Probe (issue 31, "make the detector hold"): every run's per-view, per-frame scores on the peer set,
dumped once so that ways of fusing the views can be compared without replaying anything.

Run (after bench_peer.py has built its memories under the peer cache's `runs/`):
    .venv/bin/python -m bench.experiments.probe_peer_views dump [--encoder SPEC --swapped SPEC]
    .venv/bin/python -m bench.experiments.probe_peer_views fuse

`dump` replays, per ID half, the memory half's runs (successes and failures) with their own episode
left out of both memories, the other half's runs, and the OOD runs (with and without 2 deployment
successes per task moved into the success memory), keeping each view's contrast C_t per frame, into
`<cache>/probe-views/<slug>.npz`. `fuse` reads them and prints recall, FPR, T_s and AUC of each
fusion (bench_peer_fusion.py's candidates) at α = 0.05 on both halves and the OOD cells.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from bench._timing import print_machine
from bench.bench_peer import peer_set
from robofailring.data.selection import DataSelection
from robofailring.detection.detector import FailureDetector
from robofailring.detection.rules import CONTRAST
from robofailring.encoders import encoder_slug, load_encoder, open_encoder
from robofailring.evaluation.deployment import deploy_successes
from robofailring.evaluation.job import EvaluateConfig, select_splits
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import MemoryRecipe


def _runs(
    detector: FailureDetector, trajectories: list[Any], *, loo: bool, cell: str
) -> list[dict[str, Any]]:
    found = []
    for trajectory in trajectories:
        trace = detector.run(trajectory, leave_one_out=loo, keep_queries=False)
        found.append(
            {
                "cell": cell,
                "key": trajectory.key,
                "task": trajectory.task,
                "failure": trajectory.is_failure,
                "onset": -1 if trajectory.onset_frame is None else int(trajectory.onset_frame),
                "scores": {v: s.astype(np.float32) for v, s in trace.scores_of(CONTRAST).items()},
            }
        )
    return found


def dump(spec: str, labels: Path, memory_dir: Path, out: Path) -> None:
    peer = peer_set(None, 2)
    encoder = open_encoder(spec)
    base = EvaluateConfig(data=DataSelection(peer.root, labels=labels), out=out, recipe=MemoryRecipe(spec))
    splits = select_splits(base)
    ood = select_splits(replace(base, test_split="ood")).test
    memory = FailureMemory.load(memory_dir)
    detector = FailureDetector(memory, encoder, k=5)
    runs = _runs(detector, splits.train, loo=True, cell="train")
    runs += _runs(detector, splits.test, loo=False, cell="test")
    runs += _runs(detector, ood, loo=False, cell="ood")
    deployed, rest, _ = deploy_successes(memory, ood, 2, encoder, base.recipe.success_step)
    runs += _runs(FailureDetector(deployed, encoder, k=5), rest, loo=False, cell="ood+2")
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = [{k: v for k, v in run.items() if k != "scores"} for run in runs]
    arrays = {f"{i}:{view}": values for i, run in enumerate(runs) for view, values in run["scores"].items()}
    np.savez_compressed(out, meta=json.dumps(meta), **arrays)
    print(f"dumped {len(runs)} runs to {out}")


def load(path: Path) -> list[dict[str, Any]]:
    data = np.load(path)
    meta = json.loads(str(data["meta"]))
    for i, run in enumerate(meta):
        run["scores"] = {key.split(":", 1)[1]: data[key] for key in data.files if key.startswith(f"{i}:")}
    return meta


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("what", choices=["dump"])
    parser.add_argument("--encoder", default="pixels")
    parser.add_argument("--swapped", default=None, help="the swapped half's encoder (default: --encoder)")
    args = parser.parse_args()
    print_machine()
    peer = peer_set(None, 2)
    cache = peer.root.parent
    slug = encoder_slug(load_encoder(args.encoder).identity)
    for labels, spec, suffix in (
        (peer.labels, args.encoder, ""),
        (peer.swapped_labels, args.swapped or args.encoder, "-swapped"),
    ):
        dump(
            spec,
            labels,
            cache / "runs" / f"{slug}{suffix}" / "memory",
            cache / "probe-views" / f"{slug}{suffix}.npz",
        )


if __name__ == "__main__":
    main()
