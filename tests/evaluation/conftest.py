"""The one-task dataset and memory that the band and the per-view fusion tests calibrate, built once."""

from __future__ import annotations

from pathlib import Path

import pytest
from synthetic import write_project_dataset

from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.recipe import MemoryRecipe


@pytest.fixture(scope="session")
def calibration_set(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """(data, memory, encoder cache): 24 episodes of one task, 12 training successes (α ≥ 1/13).

    Shared: a test that calibrates copies the memory first; the encoder cache only gains the same
    frames' entries.
    """
    root = tmp_path_factory.mktemp("calibration-set")
    data = write_project_dataset(
        root / "data", tasks=("pick_cube",), symbols=("grasp_wp2", "slip_wp3"), episodes=24, length=8
    )
    build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=root / "memory",
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=root / "c"),
            split="train",
        )
    )
    return data, root / "memory", root / "c"
