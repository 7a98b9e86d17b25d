"""Settings given on the command line end up in what is stored (issue 50): `--signal-start-weight` in the
memory's signal vectors and manifest, kept for a task the memory grows by (`--add-to`), and `--band-scope`
in the calibration stored in its manifest."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli
from synthetic import write_project_dataset

from robofailring import FailureMemory, load_dataset
from robofailring.memory.signals.layout import read_features

WEIGHT = 0.25  # neither the default (0) nor the weight of memories from before the setting (0.5)
STATE = 1  # the signal vectors start with the weighted start state: the gripper's width, one dimension


@pytest.fixture(scope="module")
def picks(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One task with 10 training successes: enough for a band of its own (docs/rules.md)."""
    return write_project_dataset(
        tmp_path_factory.mktemp("settings") / "picks",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=20,
        length=6,
        signals=True,
    )


@pytest.fixture(scope="module")
def pushes(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Another task, to grow the memory by."""
    return write_project_dataset(
        tmp_path_factory.mktemp("settings") / "pushes",
        tasks=("push_cube",),
        symbols=("slip_wp3",),
        episodes=2,
        length=6,
        signals=True,
    )


def _manifest(memory: Path) -> dict:  # type: ignore[type-arg]
    return json.loads((memory / "manifest.json").read_text())


def _success_vectors(memory: Path, task: str) -> np.ndarray:
    signals = FailureMemory.load(memory).signals
    assert signals is not None
    found = signals.task(task)
    assert found is not None
    return found.vectors["success"]


def test_the_signal_start_weight_given_is_the_memorys_and_a_new_task_grown_into_it_keeps_it(
    picks: Path, pushes: Path, cache: list[str], tmp_path: Path
) -> None:
    memory = tmp_path / "memory"
    built = cli(
        "build-memory", picks, "--out", memory, "--split", "train", "--signal-start-weight", WEIGHT, *cache
    )
    assert built.exit_code == 0, built.output
    assert _manifest(memory)["signals"]["start_weight"] == WEIGHT
    assert np.abs(_success_vectors(memory, "pick_cube")[:, :STATE]).max() > 0  # the start state is in

    grown = cli("build-memory", pushes, "--add-to", memory, *cache)
    assert grown.exit_code == 0, grown.output
    assert _manifest(memory)["signals"]["start_weight"] == WEIGHT
    grown_memory = FailureMemory.load(memory)
    assert grown_memory.recipe.signal_start_weight == WEIGHT
    assert grown_memory.signals is not None and set(grown_memory.signals.by_task) == {
        "pick_cube",
        "push_cube",
    }
    task = grown_memory.signals.task("push_cube")
    assert task is not None and task.start_weight == WEIGHT
    run = next(t for t in load_dataset(pushes) if not t.is_failure)  # a success's rows: its paired features
    stored = task.vectors["success"][task.rows["success"].episodes == run.episode]
    np.testing.assert_allclose(stored, task.vectors_of(read_features(run, task.layout)), atol=1e-5)
    # the new task's vectors are those a memory of it alone built at the same weight has
    alone = tmp_path / "alone"
    made = cli("build-memory", pushes, "--out", alone, "--signal-start-weight", WEIGHT, *cache)
    assert made.exit_code == 0, made.output
    added, expected = _success_vectors(memory, "push_cube"), _success_vectors(alone, "push_cube")
    assert np.abs(expected[:, :STATE]).max() > 0
    np.testing.assert_allclose(added, expected, atol=1e-6)


def test_the_band_scope_given_is_the_stored_calibrations(
    picks: Path, cache: list[str], tmp_path: Path
) -> None:
    memory = tmp_path / "memory"
    assert cli("build-memory", picks, "--out", memory, "--split", "train", *cache).exit_code == 0
    calibrated = cli(
        "calibrate", picks, "--memory", memory, "--target-fpr", "0.1", "--band-scope", "task", *cache
    )
    assert calibrated.exit_code == 0, calibrated.output
    stored = _manifest(memory)["calibration"]
    assert "a band per task" in stored["method"]
    assert set(stored["rules"]["contrast"]["band"]["tasks"]) == {"pick_cube"}  # 10 runs: a band of its own
    pooled = cli("calibrate", picks, "--memory", memory, "--target-fpr", "0.1", *cache)
    assert pooled.exit_code == 0, pooled.output
    stored = _manifest(memory)["calibration"]
    assert "a band per task" not in stored["method"] and "tasks" not in stored["rules"]["contrast"]["band"]
