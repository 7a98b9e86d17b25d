"""Derived signal features (issue 41): each dimension's change over the last frame and, for step-like
dimensions (a gripper), its jumps so far and the frames since the last, fitted on a task's successes,
computed causally, kept with the memory and read back; a memory from before them reads as `none`."""

from __future__ import annotations

import json
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from synthetic import robot_signals, write_project_dataset

from robofailring import CachedEncoder, FailureMemory, load_dataset
from robofailring.detection.signal_scores import SignalHistory
from robofailring.errors import SettingError
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.recipe import MemoryRecipe
from robofailring.memory.signals.derived import Derivation, RunningDerivation, SignalFeatures
from robofailring.memory.signals.layout import ACTION_LAGS
from robofailring.memory.signals.memory import SignalMemory, TaskSignals
from robofailring.memory.signals.section import SignalSection

LENGTH = 8


def _raw(symbol: str | None, episode: int) -> np.ndarray:
    """[width ‖ x ‖ command ‖ t], as a layout of gripper_width and action reads them."""
    found = robot_signals(symbol, LENGTH, episode)
    return np.concatenate(
        [found["gripper_width"], found["action"], np.arange(LENGTH, dtype=np.float64)[:, None]], axis=1
    )


def test_the_gripper_is_found_step_like_and_its_events_counted() -> None:
    successes = [_raw(None, 0), _raw(None, 1)]
    derivation = Derivation.fit(("change", "events"), 3, successes)
    # the width and the command jump once (at frame 4) and hold; x moves every frame
    assert derivation.steps.tolist() == [0, 2]
    np.testing.assert_allclose(derivation.tolerance, [0.05 * 0.04, 0.05 * 0.08])
    assert derivation.width == 3 + 2 * 2
    added = derivation.added(_raw("grasp_wp2", 0))  # closes on nothing: 0.08 → 0.0 at frame 4
    np.testing.assert_allclose(added[:, 0], [0, 0, 0, 0, -0.08, 0, 0, 0], atol=1e-12)  # width's change
    np.testing.assert_allclose(added[1:, 1], 0.1 / (LENGTH - 1))  # x's change, every frame
    np.testing.assert_array_equal(added[:, 3], [0, 0, 0, 0, 1, 1, 1, 1])  # the width's jumps so far
    np.testing.assert_array_equal(added[:, 5], [0, 1, 2, 3, 0, 1, 2, 3])  # frames since its last jump
    np.testing.assert_array_equal(added[:, 6], [0, 1, 2, 3, 0, 1, 2, 3])  # the command's
    # causal: a prefix of the run derives the prefix of its features
    np.testing.assert_array_equal(derivation.added(_raw("grasp_wp2", 0)[:5]), added[:5])
    assert derivation.names(["w", "x", "c"])[3:] == [
        "w (jumps so far)",
        "c (jumps so far)",
        "w (frames since its last jump)",
        "c (frames since its last jump)",
    ]
    only_change = Derivation.fit(("change",), 3, successes)
    assert only_change.width == 3 and only_change.added(_raw(None, 0)).shape == (LENGTH, 3)


def test_the_features_choice_parses_or_is_refused() -> None:
    assert SignalFeatures.parse("events,change").kinds == ("change", "events")
    assert SignalFeatures.parse("none").kinds == ()
    assert str(SignalFeatures.parse(" events,change")) == " events,change"  # the text as given, kept
    assert MemoryRecipe().signal_features == SignalFeatures.parse("change,events")
    assert str(MemoryRecipe().signal_features) == "change,events"
    assert MemoryRecipe(signal_features="events").signal_features.kinds == ("events",)
    with pytest.raises(SettingError, match="--signal-features takes none or change, events"):
        MemoryRecipe(signal_features="jerk")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("derived") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2", "slip_wp3"),
        episodes=4,
        length=LENGTH,
        signals=True,
    )


def test_a_memory_keeps_its_derived_features_and_a_live_session_derives_them_alike(
    dataset: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    train = load_dataset(dataset).select(split="train")
    memory, _ = build_memories(train, encoder, provenance=Provenance(data=dataset, encoder="pixels"))
    assert memory.signals is not None and str(memory.recipe.signal_features) == "change,events"
    task = memory.signals.task("pick_cube")
    assert task is not None and task.derivation is not None and task.layout.derived == ("change", "events")
    state = 1 + 3 + 2 * 2  # the width, 3 changes, 2 step-like dimensions' jumps and frames since
    assert task.widths == (state, 2)
    assert task.vectors["success"].shape[1] == 2 * state + len(ACTION_LAGS) * 2 + 1
    assert len(task.mean) == state + 2 + 1  # normalised after deriving

    saved = memory.save(tmp_path / "memory")
    section = json.loads((saved / "manifest.json").read_text())["signals"]
    assert section["features"] == "change,events"
    assert section["tasks"]["pick_cube"]["layout"]["derived"] == ["change", "events"]
    loaded = FailureMemory.load(saved)
    assert str(loaded.recipe.signal_features) == "change,events" and loaded.signals is not None
    again = loaded.signals.task("pick_cube")
    assert again is not None and again.derivation is not None
    np.testing.assert_array_equal(again.derivation.steps, task.derivation.steps)
    np.testing.assert_array_equal(again.vectors["failure"], task.vectors["failure"])

    run = next(t for t in load_dataset(dataset).select(split="test") if t.symbol == "grasp_wp2")
    values, _ = run.read_signals()
    whole = task.vectors_of(_raw("grasp_wp2", int(run.episode.rsplit("episode", 1)[1])))
    history = SignalHistory(again)
    for t in range(LENGTH):
        *_, vector, _, _ = history.step(
            {name: values[name].values[t] for name in ("gripper_width", "action")}, exclude_episode=None
        )
        np.testing.assert_allclose(vector, whole[t], rtol=1e-5, atol=1e-5)


def test_a_memory_from_before_derived_features_reads_as_none(
    dataset: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    train = load_dataset(dataset).select(split="train")
    memory, _ = build_memories(
        train,
        encoder,
        provenance=Provenance(data=dataset, encoder="pixels"),
        recipe=MemoryRecipe(signal_features="none"),
    )
    saved = memory.save(tmp_path / "memory")
    manifest = json.loads((saved / "manifest.json").read_text())
    del manifest["signals"]["features"]  # what a memory written before derived features holds
    assert "derived" not in manifest["signals"]["tasks"]["pick_cube"]["layout"]
    (saved / "manifest.json").write_text(json.dumps(manifest))
    loaded = FailureMemory.load(saved)
    assert str(loaded.recipe.signal_features) == "none" and loaded.signals is not None
    task = loaded.signals.task("pick_cube")
    assert task is not None and task.derivation is None and task.widths == (1, 2)
    assert str(SignalMemory.read(saved, SignalSection.parse(manifest["signals"], saved)).features) == "none"


def test_the_running_derivation_gives_each_frame_what_the_whole_run_does() -> None:
    """A live session derives frame by frame (`RunningDerivation`) what a whole run derives at once."""
    successes = [_raw(None, 0), _raw(None, 1)]
    derivation = Derivation.fit(("change", "events"), 3, successes)
    generator = np.random.default_rng(0)
    long = np.concatenate([_raw("grasp_wp2", e % 3) for e in range(40)])  # the gripper jumps again and again
    long[:, :3] += generator.normal(0, 1e-4, (len(long), 3))
    long[:, 3] = np.arange(len(long))
    whole = derivation.added(long)
    running = RunningDerivation(derivation)
    for t, row in enumerate(long):
        added, after = running.add(row)
        assert running.frames == t and after.frames == t + 1  # the one before is left as it was
        np.testing.assert_array_equal(added, whole[t])
        running = after


def _held(value: object, seen: set[int] | None = None) -> int:
    """Bytes of the numpy arrays `value` holds (its attributes, containers and dataclasses, recursively)."""
    seen = set() if seen is None else seen
    if id(value) in seen or isinstance(value, (str, bytes, int, float)) or value is None:
        return 0
    seen.add(id(value))
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, (list, tuple, deque)):
        return sum(_held(item, seen) for item in value)
    if isinstance(value, dict):
        return sum(_held(item, seen) for item in value.values())
    return sum(_held(item, seen) for item in getattr(value, "__dict__", {}).values())


def test_a_live_step_touches_as_many_rows_and_holds_as_much_at_step_5000_as_at_step_10(
    dataset: Path, encoder: CachedEncoder, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 50: a live session's derived features are kept incrementally, so neither the rows a step
    derives and pairs nor what the session holds grows with its length (counted, not timed)."""
    train = load_dataset(dataset).select(split="train")
    memory, _ = build_memories(train, encoder, provenance=Provenance(data=dataset, encoder="pixels"))
    assert memory.signals is not None
    task = memory.signals.task("pick_cube")
    assert task is not None and task.derivation is not None
    touched: list[int] = []  # rows of the features each derivation or pairing of this step reads

    def counted(method: Any) -> Any:
        def wrapper(self: object, features: np.ndarray, *args: Any, **kwargs: Any) -> Any:
            touched.append(len(np.atleast_2d(features)))
            return method(self, features, *args, **kwargs)

        return wrapper

    for owner, name in ((Derivation, "added"), (TaskSignals, "vectors_of"), (TaskSignals, "derived")):
        monkeypatch.setattr(owner, name, counted(getattr(owner, name)))
    monkeypatch.setattr(TaskSignals, "paired", counted(TaskSignals.paired))
    run = next(t for t in load_dataset(dataset).select(split="test") if t.symbol == "grasp_wp2")
    values, _ = run.read_signals()
    history = SignalHistory(task)
    work, held = {}, {}
    for step in range(5001):
        touched.clear()
        history.step(
            {name: values[name].values[step % LENGTH] for name in ("gripper_width", "action")},
            exclude_episode=None,
        )
        if step in (10, 5000):
            work[step], held[step] = sum(touched), _held(history)
    assert work[5000] == work[10] > 0
    assert held[5000] == held[10]
