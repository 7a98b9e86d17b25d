"""Probe (issue 41): every run's per-view contrast C_t (camera views and `signals`) in each cell of the
embedded and the peer benchmarks, dumped once, so that ways of fusing and calibrating the views can be
compared offline (`probe_fusion_calibration.py`) exactly as the library calibrates and judges them.

Run: .venv/bin/python -m bench.experiments.probe_fusion_dump {embedded,peer}
     [--start-weight W] [--out FILE]

Per ID half (ID, swapped): the memory half's success runs with their own episode left out of both memories
(what calibration scores), the other half's runs, the OOD runs, and with 2 OOD success runs per task moved
into both success memories (bench_quality's deployment cell) the calibration runs again and the rest of the
OOD runs. The embedded set is bench_quality's (under $ROBOFAILRING_CACHE/bench-quality), the peer set
bench_peer's LeRobot export with its chosen dimensions (CHOSEN). `--start-weight` sets the signal vectors'
start-state weight (the library's START_WEIGHT, 0.5) for this run only.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

import robofailring.memory.signals.memory as signal_memory
from bench._timing import print_machine
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.detector import FailureDetector
from robofailring.detection.rules import CONTRAST
from robofailring.encoders import default_cache_dir
from robofailring.evaluation.deployment import deploy_successes
from robofailring.evaluation.job import (
    EvaluateConfig,
    build_training_memory,
    evaluation_encoder,
    select_splits,
)
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import MemoryRecipe


def _runs(
    detector: FailureDetector, trajectories: list[Any], *, loo: bool, cell: str
) -> list[dict[str, Any]]:
    found = []
    for trajectory in trajectories:
        if trajectory.task not in detector.memory.tasks:
            continue
        trace = detector.run(trajectory, leave_one_out=loo, keep_queries=False)
        found.append(
            {
                "cell": cell,
                "key": trajectory.key,
                "task": trajectory.task,
                "failure": trajectory.is_failure,
                "onset": -1 if trajectory.onset_frame is None else int(trajectory.onset_frame),
                "scores": {v: np.asarray(s, np.float32) for v, s in trace.scores_of(CONTRAST).items()},
            }
        )
    return found


def dump_half(config: EvaluateConfig, ood_config: EvaluateConfig, half: str) -> list[dict[str, Any]]:
    splits = select_splits(config)
    encoder = evaluation_encoder(config)
    with tempfile.TemporaryDirectory() as scratch:
        config = replace(config, memory_out=Path(scratch) / "memory")
        memory = FailureMemory.load(build_training_memory(config, splits, encoder)[0])
    detector = FailureDetector(memory, encoder, k=config.scoring.k)
    calibration = [t for t in splits.train if not t.is_failure]
    runs = _runs(detector, calibration, loo=True, cell=f"{half}/cal")
    runs += _runs(detector, splits.test, loo=False, cell=f"{half}/test")
    if ood_config is not None:
        ood = select_splits(ood_config).test
        runs += _runs(detector, ood, loo=False, cell=f"{half}/ood")
        deployed, rest, _ = deploy_successes(memory, ood, 2, encoder, config.recipe.success_step)
        again = FailureDetector(deployed, encoder, k=config.scoring.k)
        runs += _runs(again, calibration, loo=True, cell=f"{half}/cal+2")
        runs += _runs(again, rest, loo=False, cell=f"{half}/ood+2")
    return runs


def configs(which: str) -> list[tuple[str, EvaluateConfig, EvaluateConfig]]:
    policy = ThresholdPolicy(target_fpr=0.05)
    if which == "embedded":
        root = default_cache_dir() / "bench-quality"
        base = EvaluateConfig(
            data=DataSelection(root / "sim-id"),
            recipe=MemoryRecipe(encoder="pixels"),
            out=Path("unused"),
            threshold_policy=policy,
        )
        ood = replace(base, test_data=base.data.other(root / "sim-ood"), test_split="ood")
        return [
            ("id", base, ood),
            ("swapped", replace(base, data=DataSelection(root / "sim-id-swapped")), ood),
        ]
    from bench.bench_peer import CHOSEN, peer_set

    peer = peer_set(None, 2)
    base = EvaluateConfig(
        data=DataSelection(peer.lerobot, labels=peer.lerobot_labels),
        recipe=MemoryRecipe(encoder="pixels", signals=CHOSEN),
        out=Path("unused"),
        threshold_policy=policy,
    )
    ood = replace(base, test_split="ood")
    swapped = replace(base, data=replace(base.data, labels=peer.lerobot_swapped))
    return [("id", base, ood), ("swapped", swapped, None)]  # type: ignore[list-item]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("set", choices=["embedded", "peer"])
    parser.add_argument("--start-weight", type=float, default=signal_memory.START_WEIGHT)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    print_machine()
    signal_memory.START_WEIGHT = args.start_weight  # type: ignore[misc]  # read at call time
    runs = []
    for half, config, ood in configs(args.set):
        runs += dump_half(config, ood, half)
    out = args.out or default_cache_dir() / "probe-fusion" / f"{args.set}-sw{args.start_weight:g}.npz"
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = [{k: v for k, v in run.items() if k != "scores"} for run in runs]
    arrays = {f"{i}:{view}": values for i, run in enumerate(runs) for view, values in run["scores"].items()}
    np.savez_compressed(out, meta=json.dumps(meta), **arrays)
    print(f"dumped {len(runs)} runs to {out}")


if __name__ == "__main__":
    main()
