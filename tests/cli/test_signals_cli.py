"""The robot's signals through the command line (issue 41): build-memory --signals, calibrate and detect
--modality, detect --json's signals section, and thresholds calibrated for one modality not used by another."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli, refused
from synthetic import write_project_dataset


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("signals-cli") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=6,
        length=8,
        signals=True,
    )


def test_build_calibrate_and_detect_with_the_robots_signals(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    memory = tmp_path / "memory"
    built = cli("build-memory", data, "--out", memory, "--split", "train", *cache)
    assert built.exit_code == 0, built.output
    manifest = json.loads((memory / "manifest.json").read_text())
    assert manifest["signals"]["choice"] == "auto" and (memory / "signals.npz").is_file()

    calibrated = cli(
        "calibrate", data, "--memory", memory, "--target-fpr", "0.34", "--modality", "signals", *cache
    )
    assert calibrated.exit_code == 0, calibrated.output
    assert json.loads((memory / "manifest.json").read_text())["calibration"]["modality"] == "signals"

    episode = "pick_cube_grasp_wp2_episode1"
    found = cli(
        "detect", data, "--memory", memory, "--trajectory", episode, "--json", "--modality", "signals", *cache
    )
    assert found.exit_code == 0, found.output
    trace = json.loads(found.stdout)
    assert trace["modality"] == "signals" and trace["signals"] is not None
    assert len(trace["signals"]["failure_similarity"]) == 8 and "contrast" in trace["signals"]
    assert trace["thresholds"]["contrast"] == manifest_threshold(memory) != 0.0
    # the thresholds were calibrated on the signals alone: judging by both falls back to the default γ = 0
    both = cli("detect", data, "--memory", memory, "--trajectory", episode, *cache)
    assert both.exit_code == 0 and "rule contrast: C_t ≥ γ = 0.000" in both.output

    refused(
        cli("build-memory", data, "--out", tmp_path / "m2", "--signals", "a,,b", *cache), 2, "--signals takes"
    )
    none = tmp_path / "none"
    assert cli("build-memory", data, "--out", none, "--signals", "none", *cache).exit_code == 0
    refused(
        cli("detect", data, "--memory", none, "--trajectory", episode, "--modality", "signals", *cache),
        2,
        "--modality signals needs a memory with the robot's signals",
    )


def manifest_threshold(memory: Path) -> float:
    return float(
        json.loads((memory / "manifest.json").read_text())["calibration"]["rules"]["contrast"]["threshold"]
    )


def test_watch_streams_the_signals_and_scores_them_live(data: Path, cache: list[str], tmp_path: Path) -> None:
    from rrd import rows

    from rfr_viz.paths import REPLAY, signal

    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    saved = tmp_path / "live.rrd"
    episode = data / "pick_cube_grasp_wp2_episode1"
    watched = cli(
        "watch", episode, "--memory", memory, "--gamma", "0.05", "--speed", "0", "--save", saved, *cache
    )
    assert watched.exit_code == 0, watched.output
    width = rows(saved, signal("gripper_width"), "Scalars:scalars")
    assert [frame for frame, _ in width] == list(range(8))
    assert [round(value[0], 3) for _, value in width][-1] == 0.001  # closed on nothing (episode 1's offset)
    scored = rows(saved, REPLAY.score("signals", "contrast"), "Scalars:scalars")
    assert [frame for frame, _ in scored] == list(range(8))
    assert max(value[0] for _, value in scored[4:]) > 0.05  # after the gripper closed on nothing
    assert "FAILURE at frame" in watched.stdout
    # the signals' S⁺_t at their own /score/signals/success, as a replay has it (detect --json's values)
    plus = rows(saved, REPLAY.success_score("signals"), "Scalars:scalars")
    found = cli("detect", data, "--memory", memory, "--trajectory", episode.name, "--json", *cache)
    assert found.exit_code == 0, found.output
    expected = json.loads(found.stdout)["signals"]["success_similarity"]
    assert [frame for frame, _ in plus] == [t for t, value in enumerate(expected) if value is not None]
    np.testing.assert_allclose(
        [value[0] for _, value in plus], [v for v in expected if v is not None], atol=1e-4
    )


def test_the_start_weight_and_band_scope_reach_the_memory_and_a_new_task_grown_keeps_the_weight(
    cache: list[str], tmp_path: Path
) -> None:
    """Issue 50: `--signal-start-weight` and `--band-scope` given on the command line are the ones used (not
    only their defaults), and a task first added by `--add-to` is built with the memory's start weight."""
    import numpy as np

    from robofailring import FailureMemory, load_dataset
    from robofailring.memory.signal_layout import read_features

    data, more = (
        write_project_dataset(
            tmp_path / task, tasks=(task,), symbols=("grasp_wp2",), episodes=2, length=8, signals=True
        )
        for task in ("pick_cube", "push_cube")
    )
    memory = tmp_path / "memory"
    built = cli("build-memory", data, "--out", memory, "--signal-start-weight", "0.7", *cache)
    assert built.exit_code == 0, built.output
    assert json.loads((memory / "manifest.json").read_text())["signals"]["start_weight"] == 0.7
    grown = cli("build-memory", more, "--add-to", memory, *cache)
    assert grown.exit_code == 0, grown.output
    signals = FailureMemory.load(memory).signals
    assert signals is not None and set(signals.by_task) == {"pick_cube", "push_cube"}
    task = signals.task("push_cube")
    assert task is not None and task.start_weight == 0.7
    run = next(t for t in load_dataset(more) if not t.is_failure)
    stored = task.vectors["success"][task.rows["success"].episodes == run.episode]
    expected = task.vectors_of(read_features(run, task.layout))  # [0.7·z_0 ‖ z_t − z_0 ‖ …]
    np.testing.assert_allclose(stored, expected, atol=1e-5)
    assert np.abs(stored[:, : task.widths[0]]).max() > 0  # the start state is in, weighted

    calibrated = cli(
        "calibrate", data, "--memory", memory, "--target-fpr", "0.5", "--band-scope", "task", *cache
    )
    assert calibrated.exit_code == 0, calibrated.output
    method = json.loads((memory / "manifest.json").read_text())["calibration"]["method"]
    assert "a band per task with enough runs" in method
