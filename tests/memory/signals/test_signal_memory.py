"""The signal memory (issue 41 item 3): built beside the failure and success memories from the robot's
signals, saved in the memory's folder and read back whole; grown with new runs; left out on request."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureMemory, load_dataset
from robofailring.errors import SettingError
from robofailring.memory.builder import Provenance, add_to, build_memories
from robofailring.memory.recipe import MemoryRecipe
from robofailring.memory.signals.layout import ACTION_LAGS
from robofailring.memory.signals.section import SIGNALS_FILE

LENGTH = 8


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("signals") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2", "slip_wp3"),
        episodes=4,
        length=LENGTH,
        signals=True,
    )


def _build(dataset: Path, encoder: CachedEncoder, **recipe: str | float) -> FailureMemory:
    train = load_dataset(dataset).select(split="train")
    memory, _ = build_memories(
        train, encoder, provenance=Provenance(data=dataset, encoder="pixels"), recipe=MemoryRecipe(**recipe)
    )
    return memory


def test_the_signal_memory_holds_every_failure_frame_from_onset_and_every_success_frame(
    dataset: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    memory = _build(dataset, encoder, signal_features="none")  # the raw features alone (derived: below)
    assert memory.recipe.signals == "auto" and memory.signals is not None
    task = memory.signals.task("pick_cube")
    assert task is not None
    assert task.layout.names == ["gripper_width", "action"]
    # 2 failure kinds x 2 train episodes, frames 1..7 (no onset recorded); 2 train successes, every frame
    assert len(task.vectors["failure"]) == 4 * (LENGTH - 1) and len(task.vectors["success"]) == 2 * LENGTH
    width = 2 * 1 + len(ACTION_LAGS) * 2 + 1  # start and change of 1 state dim, 3 lags of 2 actions, time
    assert task.vectors["failure"].shape[1] == width
    assert sorted(set(task.rows["failure"].symbols.tolist())) == ["grasp_wp2", "slip_wp3"]
    assert task.rows["failure"].frames.min() == 1 and set(task.rows["success"].symbols.tolist()) == {""}
    # normalised by the task's successes: their features have mean 0 and spread 1 (where they vary)
    np.testing.assert_allclose(task.mean[0], np.mean([0.08] * 8 + [0.04] * 8) + 0.001, atol=1e-9)

    saved = memory.save(tmp_path / "memory")
    section = json.loads((saved / "manifest.json").read_text())["signals"]
    assert section["file"] == SIGNALS_FILE and section["choice"] == "auto"
    assert section["tasks"]["pick_cube"]["failure_entries"] == 4 * (LENGTH - 1)
    loaded = FailureMemory.load(saved)
    assert loaded.signals is not None and loaded.recipe.signals == "auto"
    again = loaded.signals.task("pick_cube")
    assert again is not None and again.layout == task.layout
    for kind in ("failure", "success"):
        np.testing.assert_array_equal(again.vectors[kind], task.vectors[kind])
        assert again.rows[kind].episodes.tolist() == task.rows[kind].episodes.tolist()
    np.testing.assert_array_equal(again.scale, task.scale)


def test_no_signal_memory_when_asked_for_none_or_the_data_has_none(
    dataset: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    memory = _build(dataset, encoder, signals="none")
    assert memory.signals is None and memory.recipe.signals == "none"
    saved = memory.save(tmp_path / "memory")
    assert not (saved / SIGNALS_FILE).exists() and FailureMemory.load(saved).signals is None
    plain = write_project_dataset(
        tmp_path / "plain", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2
    )
    assert _build(plain, encoder).signals is None  # auto on data without signals: the cameras alone


def test_signals_named_are_the_only_ones_used_and_an_unknown_name_is_refused(
    dataset: Path, encoder: CachedEncoder
) -> None:
    memory = _build(dataset, encoder, signals="gripper_width")
    assert memory.signals is not None
    task = memory.signals.task("pick_cube")
    assert task is not None and task.layout.names == ["gripper_width"] and task.layout.action == ()
    with pytest.raises(Exception, match=r"--signals joint_states: .*no signal 'joint_states'"):
        _build(dataset, encoder, signals="joint_states")
    with pytest.raises(SettingError, match="--signals takes auto, none or signals separated by commas"):
        MemoryRecipe(signals="a,,b")


def test_some_dimensions_of_a_signal_are_chosen_by_glob(dataset: Path, encoder: CachedEncoder) -> None:
    """`NAME:GLOB` keeps the dimensions a glob matches (a LeRobot `observation.state` holds joints, gripper
    and pose in one vector); the live step takes the whole signal and cuts it the same way."""
    memory = _build(dataset, encoder, signals="gripper_width,action:grip*", signal_features="none")
    assert memory.signals is not None
    task = memory.signals.task("pick_cube")
    assert task is not None
    assert task.layout.state == (("gripper_width", ("width",)),)
    assert task.layout.action == (("action", ("gripper",)),)
    assert task.layout.full == {"action": ("x", "gripper")}
    width = 2 * 1 + len(ACTION_LAGS) * 1 + 1
    assert task.vectors["failure"].shape[1] == width
    from robofailring.detection.signal_scores import SignalHistory

    history = SignalHistory(task)
    minus, plus, vector, _, _ = history.step(
        {"gripper_width": [0.08], "action": [0.0, 0.08]}, exclude_episode=None
    )
    assert vector.shape == (width,) and np.isfinite(minus) and np.isfinite(plus)
    with pytest.raises(Exception, match=r"no dimension of 'action' matches z\*"):
        _build(dataset, encoder, signals="action:z*")


def test_a_run_without_the_tasks_signals_is_listed_and_the_memory_grows_with_new_runs(
    dataset: Path, encoder: CachedEncoder
) -> None:
    loaded = load_dataset(dataset)
    train, test = loaded.select(split="train"), loaded.select(split="test")
    broken = replace(train[0], signals={})  # a run whose signals file was lost
    memory, stats = build_memories(
        [broken, *train[1:]], encoder, provenance=Provenance(data=dataset, encoder="pixels")
    )
    assert any(
        "signals not used" in s.reason and "no signal 'gripper_width'" in s.reason
        for s in stats.skipped_inputs
    )
    assert memory.signals is not None
    task = memory.signals.task("pick_cube")
    assert task is not None and broken.episode not in task.rows["failure"].episodes.tolist()
    before = {kind: len(v) for kind, v in task.vectors.items()}
    grown, _ = add_to(memory, test, encoder)
    assert grown.signals is not None
    after = grown.signals.task("pick_cube")
    assert after is not None
    failures = sum(t.length - 1 for t in test if t.is_failure)
    successes = sum(t.length for t in test if not t.is_failure)
    assert len(after.vectors["failure"]) == before["failure"] + failures
    assert len(after.vectors["success"]) == before["success"] + successes
    np.testing.assert_array_equal(after.mean, task.mean)  # the normalisation stays the memory's own


def test_the_start_state_weight_is_a_recipe_setting_kept_with_the_memory(
    dataset: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    half = _build(dataset, encoder, signal_features="none", signal_start_weight=0.5)
    none = _build(dataset, encoder, signal_features="none")  # the default: the start state left out
    assert half.signals is not None and none.signals is not None
    state = 1  # the gripper's width: [w·z_0 ‖ z_t − z_0 ‖ …]
    kept, dropped = half.signals.task("pick_cube"), none.signals.task("pick_cube")
    assert kept is not None and dropped is not None
    np.testing.assert_array_equal(dropped.vectors["success"][:, :state], 0.0)
    np.testing.assert_allclose(kept.vectors["success"][:, state:], dropped.vectors["success"][:, state:])
    assert np.abs(kept.vectors["success"][:, :state]).max() > 0
    saved = none.save(tmp_path / "memory")
    manifest = json.loads((saved / "manifest.json").read_text())
    assert manifest["signals"]["start_weight"] == 0.0
    loaded = FailureMemory.load(saved)
    assert loaded.recipe.signal_start_weight == 0.0 and loaded.signals is not None
    assert loaded.signals.start_weight == 0.0 and loaded.signals.task("pick_cube").start_weight == 0.0  # type: ignore[union-attr]
    # a memory from before the setting read as it was built: the start state at ½
    del manifest["signals"]["start_weight"]
    (saved / "manifest.json").write_text(json.dumps(manifest))
    old = FailureMemory.load(saved)
    assert old.recipe.signal_start_weight == 0.5 and old.signals.task("pick_cube").start_weight == 0.5  # type: ignore[union-attr]
    with pytest.raises(SettingError, match="start weight"):
        MemoryRecipe(signal_start_weight=-1.0)
