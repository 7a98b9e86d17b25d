"""The monitor's fixtures: a pixels memory with the robot's signals, saved, and its detector."""

from __future__ import annotations

from pathlib import Path

import pytest
from rollout_env import LENGTH, TASK
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureDetector, load_dataset, load_encoder, open_detector
from robofailring.memory.builder import Provenance, build_memories


@pytest.fixture(scope="session")
def monitor_memory_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The train half of a signals dataset (grasp and slip failures, successes) as a saved pixels memory."""
    root = write_project_dataset(
        tmp_path_factory.mktemp("monitor-data") / "data",
        tasks=(TASK,),
        symbols=("grasp_wp2", "slip_wp3"),
        episodes=4,
        length=LENGTH,
        signals=True,
    )
    train = [t for t in load_dataset(root).trajectories() if t.split == "train"]
    encoder = CachedEncoder(load_encoder("pixels"), enabled=False)
    memory, _ = build_memories(train, encoder, provenance=Provenance(data=root, encoder="pixels"))
    return memory.save(tmp_path_factory.mktemp("monitor-memory") / "memory")


@pytest.fixture()
def detector(monitor_memory_dir: Path) -> FailureDetector:
    """The memory's detector at γ = 0.05 (contrast: the task has successes and failures)."""
    return open_detector(monitor_memory_dir, gamma=0.05)
