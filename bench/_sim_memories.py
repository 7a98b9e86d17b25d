"""Failure memories of the simulator's episodes for the memory-map benches (bench_map_fit.py, bench_memory_map.py).

The data is the demo's simulated in-distribution set when `robofailring demo` has cached it (4 tasks × 7
failure families × 3 episodes, three cameras, 128 px, 40 frames), else the same set simulated here once
and cached. Every failure episode of every split goes into the memory: the map shows failures.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robofailring.data.layouts import load_dataset
from robofailring.encoders import default_cache_dir, open_encoder
from robofailring.memory.failure import FailureMemory
from robofailring.sim import TASKS, GenerateConfig, simulate

DEMO_DATA = "demo-data/sim-id"  # under the robofailring cache dir, written by `robofailring demo`
DEMO_TRAINED = "demo-data/trained-encoder"  # the demo's trained encoder, when it trained one


def default_data(workers: int = 2) -> Path:
    """The demo's simulated set if cached, else the same set simulated under `<cache>/bench-map`."""
    demo = default_cache_dir() / DEMO_DATA
    if (demo / "manifest.json").is_file():
        return demo
    config = GenerateConfig(
        out=default_cache_dir() / "bench-map" / "sim-id",
        tasks=TASKS,
        episodes=3,
        success_episodes=1,
        seed=0,
        image_size=128,
        frames=40,
        workers=workers,
    )
    return simulate(config)


def default_encoders() -> list[str]:
    """`pixels`, and the demo's trained encoder when the demo trained one."""
    trained = default_cache_dir() / DEMO_TRAINED
    return ["pixels"] + ([f"trained:{trained}"] if (trained / "encoder.json").is_file() else [])


@dataclass(frozen=True)
class LabelledMemory:
    spec: str
    memory: FailureMemory

    @property
    def failure_types(self) -> np.ndarray:
        from rfr_viz.panels.map import class_id

        return np.asarray([class_id(entry.symbol, entry.vocabulary) for entry in self.memory.entries])

    @property
    def views(self) -> np.ndarray:
        return np.asarray([entry.view for entry in self.memory.entries])


def failure_memory(data: Path, spec: str) -> LabelledMemory:
    """The failure memory (no success runs) of every failure episode under `data`, encoded with `spec`."""
    encoder = open_encoder(spec)
    memory, _ = FailureMemory.build(load_dataset(data), encoder)
    return LabelledMemory(spec=spec, memory=memory)


def chance_purity(labels: np.ndarray) -> float:
    """The kNN purity of a map that ignores the labels: Σ_c p_c²."""
    _, counts = np.unique(labels, return_counts=True)
    shares = counts / counts.sum()
    return float((shares**2).sum())


def in_fresh_process(script: str, *args: str) -> dict[str, float]:
    """Run `script --child ARGS…` in a new interpreter (as the first replay of a session runs) and read
    the JSON object it prints last."""
    root = str(Path(__file__).resolve().parents[1])  # the `bench` package's parent, however the parent ran
    path = os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))
    done = subprocess.run(
        [sys.executable, script, "--child", *args],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "PYTHONPATH": path},
    )
    found: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return found
