"""The robot's signals through the command line (issue 41): build-memory --signals, calibrate and detect
--modality, detect --json's signals section, and thresholds calibrated for one modality not used by another."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli, refused
from synthetic import write_project_dataset

from robofailring.data.layouts.project import PROJECT_SIGNALS, SIGNALS_FILE


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


def _as_generate_writes(root: Path) -> Path:
    """`root`'s episodes given a `signals.npz` of every signal `robofailring generate` writes, at its widths,
    described in the manifest as `generate` describes them (each run a little off the others)."""
    manifest = json.loads((root / "manifest.json").read_text())
    for number, record in enumerate(manifest["episodes"]):
        folder = root / record["dir"]
        length = len(list(folder.glob("front_*.png")))
        ramp = np.linspace(0.0, 1.0, length)[:, None] + 0.01 * number
        arrays = {
            name: ramp * (1 + np.arange(len(dims))) + (0.5 if record["label"] else 0.0) * (ramp > 0.5)
            for name, (_, dims) in PROJECT_SIGNALS.items()
        }
        np.savez(folder / SIGNALS_FILE, **arrays)  # type: ignore[arg-type]
        record["signals"] = {
            "file": SIGNALS_FILE,
            "signals": {
                name: {"kind": kind, "names": list(dims)} for name, (kind, dims) in PROJECT_SIGNALS.items()
            },
        }
    (root / "manifest.json").write_text(json.dumps(manifest))
    return root


def test_a_project_episode_copied_elsewhere_keeps_its_signals(cache: list[str], tmp_path: Path) -> None:
    """Issue 50: an episode folder of `generate`'s copied out of its dataset (no manifest beside it) is read
    with its `signals.npz` (not listed as "not part of an episode"), and scores as it does in place."""
    data = _as_generate_writes(
        write_project_dataset(tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=4)
    )
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    episode = "pick_cube_grasp_wp2_episode1"
    copied = Path(shutil.copytree(data / episode, tmp_path / "elsewhere" / episode))
    found = {}
    for where in (data / episode, copied):
        detected = cli("detect", where, "--memory", memory, "--json", *cache)
        assert detected.exit_code == 0, detected.output  # nothing skipped: the signals file is read
        assert "not part of an episode" not in detected.output
        found[where] = json.loads(detected.stdout)
    assert found[copied]["signals"] is not None
    assert found[copied]["signals"] == found[data / episode]["signals"]
    assert found[copied]["t_det"] == found[data / episode]["t_det"]


def test_detect_and_replay_agree_on_runs_without_signals_and_runs_whose_signals_break(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    """Issue 50: a camera-only dataset scored by a memory that has signals is not a fault (detect ended with
    status 3, "not read"; replay said nothing): both say, in one note, that its cameras judge alone, and
    end with 0. A run whose signals file cannot be read is listed by both, with status 3."""
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    cameras = write_project_dataset(
        tmp_path / "cameras", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=8
    )
    episode = "pick_cube_grasp_wp2_episode1"
    note = f"trajectory pick_cube/{episode} records no robot signals; the memory has its task's"
    trusted = ("--data-root", data)  # the memory's images, in another dataset than the one replayed
    detected = cli("detect", cameras, "--memory", memory, "--trajectory", episode, *trusted, *cache)
    replayed = cli(
        "replay",
        cameras,
        "--memory",
        memory,
        "--trajectory",
        episode,
        "--out",
        tmp_path / "r",
        *trusted,
        *cache,
    )
    for result in (detected, replayed):
        assert result.exit_code == 0, result.output
        assert note in result.output and "not read" not in result.output
    broken = Path(shutil.copytree(data, tmp_path / "broken"))
    (broken / episode / SIGNALS_FILE).write_bytes(b"not an npz")
    detected = cli("detect", broken, "--memory", memory, "--trajectory", episode, *cache)
    replayed = cli(
        "replay", broken, "--memory", memory, "--trajectory", episode, "--out", tmp_path / "b", *cache
    )
    for result in (detected, replayed):
        assert result.exit_code == 3, result.output
        assert f"{episode}: signals not scored (cameras alone)" in result.output
        assert f"cannot read {broken / episode / SIGNALS_FILE}" in result.output


def test_memory_info_shows_the_signal_memory(data: Path, cache: list[str], tmp_path: Path) -> None:
    """Issue 50: memory-info never mentioned the signal memory; it says which signals each task's judges,
    their dimensions, the derived features and the entries, in its text and its JSON."""
    memory, none = tmp_path / "memory", tmp_path / "none"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    assert cli("build-memory", data, "--out", none, "--signals", "none", *cache).exit_code == 0
    described = json.loads((memory / "manifest.json").read_text())["signals"]
    info = cli("memory-info", memory, "--json")
    assert info.exit_code == 0, info.output
    (held,) = json.loads(info.stdout)["signals"]["tasks"].values()
    assert held["state"] == {"gripper_width": ["width"]} and held["action"] == {"action": ["x", "gripper"]}
    assert (
        held["dimensions"] == 3
        and held["failure_entries"] == described["tasks"]["pick_cube"]["failure_entries"]
    )
    text = cli("memory-info", memory).stdout
    assert f"signals     the robot's own, chosen auto; derived features {described['features']}" in text
    assert "pick_cube  state gripper_width (1); action action (2): 3 dimensions" in text
    assert "signals     none: the cameras alone" in cli("memory-info", none).stdout
    assert json.loads(cli("memory-info", none, "--json").stdout)["signals"] is None


def test_one_modality_judges_at_the_thresholds_calibrated_for_both(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    """Issue 50: `--modality cameras` on a memory calibrated for both said it "is not calibrated" and judged
    at γ = 0. Either modality alone is a subset of the views whose max was calibrated, so its fused score
    is never higher: the thresholds (and each modality's band) of both keep their false-alarm promise."""
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    calibrated = cli("calibrate", data, "--memory", memory, "--target-fpr", "0.34", *cache)
    assert calibrated.exit_code == 0, calibrated.output
    stored = manifest_threshold(memory)
    episode = "pick_cube_grasp_wp2_episode1"
    for modality in ("cameras", "signals"):
        found = cli(
            "detect",
            data,
            "--memory",
            memory,
            "--trajectory",
            episode,
            "--json",
            "--modality",
            modality,
            *cache,
        )
        assert found.exit_code == 0, found.output
        assert "not calibrated" not in found.output
        trace = json.loads(found.stdout)
        assert trace["modality"] == modality and trace["thresholds"]["contrast"] == stored != 0.0


def test_a_damaged_signals_section_is_one_error_naming_the_manifest(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    """Issue 53: the section is read once, with the manifest, and checked there; derived features no version
    writes were shown by memory-info as if they were the memory's (and failed only when the memory grew)."""
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    manifest = json.loads((memory / "manifest.json").read_text())
    manifest["signals"]["features"] = "jerk"
    (memory / "manifest.json").write_text(json.dumps(manifest))
    refused(cli("memory-info", memory), 2, f"{memory / 'manifest.json'}", "jerk", "signal memory")
