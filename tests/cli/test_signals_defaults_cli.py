"""The signals' defaults (issue 51): `--signals auto` chooses the dimensions that separate a task's failures from its
successes on its own training runs (item 2: one dimension carries the failures, a gripper closing at the wrong
moment, three others carry where things were placed; the memory keeps the first and `memory-info` names it with
why), and an evaluation gives every figure per modality (item 3)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli
from synthetic import write_project_dataset

LENGTH = 12
RECORD = {"observation.state": {"kind": "state", "names": ["j1", "j2", "j3", "grip"]}}


def placed_signals(failed: bool, episode: int) -> np.ndarray:
    """Three joints that move as far as where the object was placed asks (a different amount each run), and a
    gripper that closes half-way through a success and at frame 2 of a failure: the same values, at the wrong
    moment."""
    rng = np.random.default_rng(episode + (1000 if failed else 0))
    t = np.arange(LENGTH, dtype=np.float64)[:, None]
    joints = rng.normal(0.0, 1.0, 3) + rng.uniform(-1.0, 1.0, 3) * t / LENGTH
    grip = np.where(t >= (2 if failed else LENGTH // 2), 0.02, 0.08)
    return np.concatenate([joints, grip], axis=1)


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = write_project_dataset(
        tmp_path_factory.mktemp("select") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=12,
        length=LENGTH,
        signals=True,
    )
    manifest = json.loads((root / "manifest.json").read_text())
    for number, record in enumerate(manifest["episodes"]):
        failed = record["outcome"] == "failure"
        np.savez(
            root / record["dir"] / "signals.npz", **{"observation.state": placed_signals(failed, number)}
        )
        record["signals"] = {"file": "signals.npz", "signals": RECORD}
    (root / "manifest.json").write_text(json.dumps(manifest))
    return root


def test_the_defaults_choose_the_dimension_that_carries_the_failures_and_memory_info_names_it(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    memory = tmp_path / "memory"
    built = cli("build-memory", data, "--out", memory, "--split", "train", *cache)
    assert built.exit_code == 0, built.output
    task = json.loads((memory / "manifest.json").read_text())["signals"]["tasks"]["pick_cube"]
    selection = task["selection"]
    chosen = [c["group"] for c in selection["chosen"]]
    assert chosen and all("grip" in name for name in chosen), chosen
    assert selection["runs"] == [6, 6] and selection["auc"] > selection["auc_all"]
    assert selection["auc"] == 1.0

    info = cli("memory-info", memory, *cache[:0])
    assert info.exit_code == 0, info.output
    assert "chosen (weight 1): observation.state/grip" in info.output
    assert "with every dimension" in info.output and "j1" not in info.output.split("chosen")[1]

    as_json = json.loads(cli("memory-info", memory, "--json").stdout)
    assert as_json["signals"]["tasks"]["pick_cube"]["selection"]["chosen"][0]["group"] == chosen[0]


def test_the_chosen_dimensions_detect_the_failures_every_dimension_misses(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    figures = {}
    for label, signals in (("auto", "auto"), ("all", "observation.state")):
        out = tmp_path / label
        result = cli(
            "evaluate",
            data,
            "--out",
            out,
            "--modality",
            "signals",
            "--signals",
            signals,
            "--target-fpr",
            "0.2",
            *cache,
        )
        assert result.exit_code == 0, result.output
        figures[label] = json.loads((out / "evaluation.json").read_text())["rules"]["contrast"]
    assert figures["auto"]["auc"] == 1.0
    assert figures["auto"]["auc"] > figures["all"]["auc"]


def test_an_evaluation_gives_the_cameras_the_signals_and_both_each_at_its_own_threshold(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    found = {}
    for modality in ("both", "cameras", "signals"):
        out = tmp_path / modality
        result = cli("evaluate", data, "--out", out, "--modality", modality, "--target-fpr", "0.2", *cache)
        assert result.exit_code == 0, result.output
        found[modality] = json.loads((out / "evaluation.json").read_text())
    fused = found["both"]
    for rule in ("contrast", "novelty"):
        rows = fused["modalities"][rule]
        assert list(rows) == ["cameras", "signals", "both"]
        for modality in ("cameras", "signals"):  # each as an evaluation of that modality alone finds it
            alone = found[modality]["rules"][rule]
            for name in ("threshold", "recall", "fpr", "ts_mean", "auc", "tp", "fp"):
                assert rows[modality][name] == alone[name], (rule, modality, name)
        for name in ("threshold", "recall", "fpr", "ts_mean", "auc"):
            assert rows["both"][name] == fused["rules"][rule][name]
        assert rows["both"]["recall_per_type"] == {"grasp": {"detected": 6, "total": 6}}
    contrast = fused["modalities"]["contrast"]
    assert contrast["signals"]["ts_mean"] == pytest.approx(
        1 / 3, abs=1e-6
    )  # the gripper closes at frame 2 of 12
    assert (
        contrast["cameras"]["ts_mean"] > 0.8
        and contrast["cameras"]["threshold"] > contrast["signals"]["threshold"]
    )
    assert "signals" in fused["rules"]["contrast"]["view_ablation"]  # the view ablation names the signals too
    assert "9 runs would let it sit below the highest" in (tmp_path / "both" / "evaluation.md").read_text()
    markdown = (tmp_path / "both" / "evaluation.md").read_text()
    assert "| contrast | signals | 0.0000 | 100.00 | 0.00 | 100.00 | 33.33 | 1.000 | 6 / 6 |" in markdown
    report = (tmp_path / "both" / "report.html").read_text()
    assert (
        "Per modality" in report
        and "<td>signals</td><td class=num>0.0000</td><td class=num>100.00</td>" in report
    )
