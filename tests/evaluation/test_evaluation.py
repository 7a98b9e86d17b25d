"""Evaluation end to end on a small dataset: splits stay apart, files are written, calibration is used."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from synthetic import write_project_dataset

from robofailring import (
    CachedEncoder,
    FailureDetector,
    FailureMemory,
    RoboFailRingError,
    load_dataset,
    load_encoder,
)
from robofailring.calibration.job import CalibrateConfig, calibrate
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import SettingError
from robofailring.evaluation.job import EvaluateConfig, run_evaluation, select_splits
from robofailring.evaluation.splits import check_disjoint
from robofailring.evaluation.written import write_evaluation
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.recipe import MemoryRecipe


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(tmp_path_factory.mktemp("project"))


def test_splits_keep_memory_and_test_apart(dataset: Path, tmp_path: Path) -> None:
    config = EvaluateConfig(
        data=DataSelection(dataset), placement=EncoderPlacement(cache_dir=tmp_path / "cache"), out=tmp_path
    )
    splits = select_splits(config)
    train, test = splits.train, splits.test
    assert {t.key for t in train}.isdisjoint({t.key for t in test})
    assert all(t.split == "train" for t in train) and all(t.split == "test" for t in test)
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    leaky, _ = FailureMemory.build(list(load_dataset(dataset)), encoder)  # built from everything
    with pytest.raises(RoboFailRingError, match="also in the memory"):
        check_disjoint(leaky, test)
    honest, _ = FailureMemory.build(train, encoder)
    check_disjoint(honest, test)
    provenance = Provenance(data=dataset, encoder="pixels")
    dense, _ = build_memories(
        list(load_dataset(dataset)),
        encoder,
        provenance=provenance,
        recipe=MemoryRecipe(failure_frames="dense"),
    )
    with pytest.raises(RoboFailRingError, match="also in the memory"):
        check_disjoint(dense, test)


def test_evaluation_files_and_counts(dataset: Path, tmp_path: Path) -> None:
    config = EvaluateConfig(
        data=DataSelection(dataset),
        threshold_policy=ThresholdPolicy(target_fpr=0.2),
        placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
        out=tmp_path,
        name="in-distribution",
    )
    result = run_evaluation(config)
    assert result.failures == 2 * 3 * 2 and result.successes == 2 * 2
    json_path, md_path = write_evaluation(result, tmp_path)
    report = json.loads(json_path.read_text())
    assert [row["delta"] for row in report["paper_deltas"]] == [0.85, 0.9, 0.92, 0.95]
    for row in report["paper_deltas"]:
        assert row["tp"] + row["fn"] == 12 and row["fp"] + row["tn"] == 4
    assert set(report["view_ablation"]) == {"front", "overhead", "wrist", "fusion"}
    assert set(report["recall_per_type"]) == {"grasp", "slip", "wrong_object"}
    assert len(report["trajectories"]) == 16 and report["latency_ms"]["total"] > 0
    assert "| 0.92 |" in md_path.read_text()
    # every rule, each calibrated on the 4 training successes at α = 0.2 (rank ⌈5 · 0.8⌉ = 4 of 4)
    assert set(report["rules"]) == {"paper", "contrast", "novelty"}
    for name, row in report["rules"].items():
        assert row["calibrated"] and row["tp"] + row["fn"] == 12 and row["fp"] + row["tn"] == 4
        assert row["recall"] == pytest.approx(row["tp"] / 12) and 0.0 <= row["auc"] <= 1.0
        assert f"| {name} |" in md_path.read_text()
    assert report["rules"]["paper"]["threshold"] == report["operating_delta"]
    # beside α, how far the test FPR can stray with 4 calibration runs: Beta(1, 4)
    for row in report["rules"].values():
        assert row["fpr_spread"]["successes"] == 4
        assert row["fpr_spread"]["high"] == pytest.approx(1 - 0.05**0.25, abs=1e-6)
    markdown = md_path.read_text()
    assert "one calibration set can miss it" in markdown
    assert (
        "- paper, contrast, novelty: with 4 calibration runs the test FPR at α = 20 % lies in 1.3–52.7 %"
        in markdown
    )
    assert (tmp_path / "memory" / "manifest.json").is_file()
    # the memory holds only training failures, dense by default, and every table says so
    memory = FailureMemory.load(tmp_path / "memory")
    assert {e.episode.rsplit("episode", 1)[1] for e in memory.entries} <= {"0", "2"}
    assert memory.manifest.failure_mode == result.failure_frames == report["failure_frames"] == "dense"
    blamed = result.false_alarm_entries(0.5)  # at δ = 0.5 every success run fires
    assert blamed and all(row["moment"] == memory.entries[row["index"]].moment for row in blamed)
    assert all(
        row["moment"].startswith("frame ") for row in blamed
    )  # a dense run's entries differ only there
    assert markdown.startswith(
        "## in-distribution — encoder `pixels-v2-24px-512d`, K = 5, dense failure memory"
    )
    assert "(dense: each failure run's frames from its onset on, thinned; `--failure-frames end`" in markdown


def test_an_evaluation_of_the_papers_memory_says_so(dataset: Path, tmp_path: Path) -> None:
    with pytest.raises(SettingError, match="failure frames must be end or dense, got 'all'"):
        EvaluateConfig(data=DataSelection(dataset), recipe=MemoryRecipe(failure_frames="all"), out=tmp_path)
    result = run_evaluation(
        EvaluateConfig(
            data=DataSelection(dataset),
            threshold_policy=ThresholdPolicy(target_fpr=0.2),
            recipe=MemoryRecipe(failure_frames="end"),
            placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
            out=tmp_path,
        )
    )
    json_path, md_path = write_evaluation(result, tmp_path)
    assert json.loads(json_path.read_text())["failure_frames"] == "end"
    markdown = md_path.read_text()
    assert ", K = 5, end failure memory" in markdown.splitlines()[0]
    assert "(end: the paper's memory, one (I_0 ‖ I_end) entry per failure view)" in markdown
    assert (
        len(FailureMemory.load(tmp_path / "memory")) == 2 * 3 * 2 * 3
    )  # one entry per training failure view


def test_calibration_is_stored_and_used(dataset: Path, tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    run_evaluation(
        EvaluateConfig(
            data=DataSelection(dataset),
            threshold_policy=ThresholdPolicy(target_fpr=0.5),
            placement=EncoderPlacement(cache_dir=cache),
            out=tmp_path,
        )
    )
    calibration = calibrate(
        CalibrateConfig(
            data=DataSelection(dataset),
            memory=tmp_path / "memory",
            placement=EncoderPlacement(cache_dir=cache),
            threshold_policy=ThresholdPolicy(target_fpr=0.5),
        )
    )
    assert calibration.successes == 4 and calibration.achieved_fprs["paper"] <= 0.5
    assert list(calibration.thresholds) == ["paper", "contrast", "novelty"]  # every rule the memory supports
    manifest = json.loads((tmp_path / "memory" / "manifest.json").read_text())
    stored = manifest["calibration"]["rules"]
    assert stored["paper"]["threshold"] == calibration.delta and stored["paper"]["runs"] == 4
    assert manifest["calibration"]["encoder"] == manifest["encoder"]
    memory = FailureMemory.load(tmp_path / "memory")
    detector = FailureDetector(memory, CachedEncoder(load_encoder("pixels"), cache_dir=cache), rule="paper")
    assert detector.delta == calibration.delta and detector.gamma == calibration.gamma
    assert stored["contrast"]["threshold"] == calibration.gamma
    assert stored["novelty"]["threshold"] == calibration.eta == detector.eta is not None
    assert {name: rule["achieved_fpr"] for name, rule in stored.items()} == calibration.achieved_fprs
    assert FailureDetector(memory, load_encoder("pixels"), delta=0.5).delta == 0.5  # --delta wins
    # on the calibration successes, the achieved FPR is what calibration reported
    successes = [t for t in load_dataset(dataset) if not t.is_failure and t.split == "train"]
    fired = sum(detector.run(t).t_det is not None for t in successes)
    assert fired / len(successes) == pytest.approx(calibration.achieved_fprs["paper"])
    contrast = FailureDetector(memory, CachedEncoder(load_encoder("pixels"), cache_dir=cache))
    fired = sum(contrast.run(t, leave_one_out=True).t_det is not None for t in successes)
    assert fired / len(successes) == pytest.approx(calibration.achieved_fprs["contrast"])


def test_too_short_test_trajectories_are_skipped_and_reported(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2)
    short = data / "pick_cube_slip_wp3_episode1"  # a test-split failure
    for image in short.glob("*.png"):
        if not image.stem.endswith("_0"):
            image.unlink()
    result = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data),
            threshold_policy=None,
            placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
            out=tmp_path / "out",
        )
    )
    assert result.skipped_too_short == ["pick_cube/pick_cube_slip_wp3_episode1"]
    assert result.failures == 2  # the other two test failures
    assert "with no view of 2 or more frames" in result.to_markdown()
