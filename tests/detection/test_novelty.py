"""The novelty rule: a task with success runs only is built, calibrated and judged by N_t = 1 − S⁺_t ≥ η."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.calibration.job import CalibrateConfig, calibrate
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.detection.rules import (
    CONTRAST,
    NOVELTY,
    PAPER,
    NoveltyRule,
    default_rule,
    rule_named,
    rules_for,
)
from robofailring.detection.view_scores import reaches
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import DataError, SettingError
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.jobs.detect import DetectConfig, run_detect
from robofailring.memory.info import MemoryInfo
from robofailring.memory.recipe import MemoryRecipe

NAN = float("nan")


def test_the_novelty_rule_scores_one_minus_s_plus_against_eta() -> None:
    assert isinstance(NOVELTY, NoveltyRule) and rule_named("novelty") is NOVELTY
    assert (NOVELTY.name, NOVELTY.symbol, NOVELTY.score_name, NOVELTY.threshold_key) == (
        "novelty",
        "η",
        "N_t",
        "eta",
    )
    assert NOVELTY.needs_successes and not NOVELTY.needs_failures and NOVELTY.bounds == (0.0, 2.0)
    np.testing.assert_allclose(NOVELTY.score([NAN, 0.9, 0.1], [0.75, NAN, -0.5]), [0.25, NAN, 1.5])
    np.testing.assert_array_equal(reaches([0.25, NAN, 1.5], 0.3), [False, False, True])
    with pytest.raises(SettingError, match=r"η must lie in \[0, 2\] for the novelty rule"):
        NOVELTY.check_threshold(-0.1)


def test_the_default_rule_follows_what_a_task_has() -> None:
    assert default_rule(successes=True, failures=True) is CONTRAST
    assert default_rule(successes=True, failures=False) is NOVELTY
    assert default_rule(successes=False, failures=True) is PAPER
    assert rules_for(successes=True, failures=False) == [NOVELTY]
    assert rules_for(successes=False) == [PAPER]


@pytest.fixture(scope="module")
def success_only(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    root = tmp_path_factory.mktemp("novelty")
    data = write_project_dataset(root / "data", tasks=("pick_cube",), symbols=(), episodes=6, length=6)
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


def test_success_runs_alone_build_a_memory_with_an_empty_failure_memory(
    success_only: tuple[Path, Path, Path],
) -> None:
    _data, memory_dir, _ = success_only
    memory = FailureMemory.load(memory_dir)
    assert len(memory) == 0 and memory.successes is not None
    assert memory.tasks == ["pick_cube"] and not memory.has_failures("pick_cube")
    assert (
        memory.task_size("pick_cube") == 0 and memory.successes.success_runs == 3 * 3
    )  # 3 train runs × 3 views
    manifest = json.loads((memory_dir / "manifest.json").read_text(encoding="utf-8"))
    assert (
        manifest["count"] == 0
        and manifest["tasks"] == {}
        and manifest["successes"]["tasks"] == {"pick_cube": 9}
    )
    sims, ids = memory.search(np.ones((2, memory.dim), np.float32) / np.sqrt(memory.dim), "pick_cube", 3)
    assert np.isnan(sims).all() and (ids == -1).all() and sims.shape == (2, 3)
    text = MemoryInfo.read(memory_dir).to_text()
    assert (
        "entries     0 × " in text
        and "no failures pick_cube: success runs only, judged by the novelty rule" in text
    )


def test_no_success_and_no_failure_is_still_an_error(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), symbols=(), episodes=2)
    with pytest.raises(
        DataError, match="--no-successes leaves out its success runs: a memory needs one or the other"
    ):
        build_memory(
            BuildMemoryConfig(
                data=DataSelection(data),
                out=tmp_path / "m",
                recipe=MemoryRecipe.chosen("pixels"),
                success_memory=False,
            )
        )
    assert not (tmp_path / "m").exists()


def test_eta_is_calibrated_on_training_successes_and_judges_the_task(
    success_only: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    data, memory_dir, cache = success_only
    memory = tmp_path / "memory"
    FailureMemory.load(memory_dir).save(memory)
    found = calibrate(
        CalibrateConfig(
            data=DataSelection(data),
            memory=memory,
            placement=EncoderPlacement(cache_dir=cache),
            threshold_policy=ThresholdPolicy(target_fpr=0.4),
        )
    )
    assert found.delta is None and found.gamma is None and found.eta is not None
    assert "η = " in found.to_text(memory) and "δ = " not in found.to_text(memory)
    stored = json.loads((memory / "manifest.json").read_text(encoding="utf-8"))["calibration"]
    assert list(stored["rules"]) == ["novelty"] and stored["rules"]["novelty"]["threshold"] == found.eta
    loaded = FailureMemory.load(memory)
    assert (
        loaded.calibrated_threshold("novelty") == found.eta and loaded.calibrated_threshold("paper") is None
    )

    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    detector = FailureDetector(loaded, encoder, k=2)
    assert (
        detector.rule is NOVELTY and detector.rule_for("pick_cube") is NOVELTY and detector.eta == found.eta
    )
    # η is the conformal bound of the leave-one-out peaks of the training successes, recomputed here
    from robofailring.calibration.conformal import conformal_threshold

    train = [t for t in load_dataset(data).select(split="train")]
    peaks = [float(detector.run(t, leave_one_out=True).max_score().max()) for t in train]
    assert found.eta == pytest.approx(conformal_threshold(peaks, 0.4))

    trajectory = load_dataset(data).select(split="test")[0]
    trace = detector.run(trajectory)
    assert trace.rule is NOVELTY and trace.threshold == found.eta
    for view in trace.views:
        np.testing.assert_allclose(trace.scores[view], 1 - trace.success_similarity[view], atol=1e-6)
        assert np.isnan(trace.similarity[view]).all()
    body = trace.to_dict()
    assert (
        body["score"] == "novelty"
        and body["thresholds"]["novelty"] == found.eta
        and body["failure_entries"] == 0
    )
    assert body["views"][trace.views[0]]["novelty"][3] == pytest.approx(
        float(1 - trace.success_similarity[trace.views[0]][3]), abs=1e-6
    )
    session = detector.session(trajectory.task)
    step = session.step({view: frames[0] for view, frames in trajectory.views.items()})
    assert step.rule is NOVELTY and step.threshold == found.eta and step.neighbors[trace.views[0]] == []
    assert step.rule_scores["novelty"][trace.views[0]] == pytest.approx(
        float(trace.scores_of(NOVELTY)[trace.views[0]][0]), abs=1e-6
    )

    for rule in ("paper", "contrast"):
        with pytest.raises(SettingError, match=f"the {rule} rule needs failure runs in the memory"):
            FailureDetector(loaded, encoder, rule=rule)


def test_detect_says_novelty_fired_with_no_failure_to_compare(
    success_only: tuple[Path, Path, Path],
) -> None:
    data, memory_dir, cache = success_only
    trajectory = load_dataset(data).select(split="test")[0]
    result = run_detect(
        DetectConfig(
            data=DataSelection(data),
            detector=DetectorConfig(
                memory=memory_dir, thresholds={"novelty": 0.0}, placement=EncoderPlacement(cache_dir=cache)
            ),
            key=trajectory.key,
        )
    )
    assert result.trace.rule is NOVELTY and result.trace.eta == 0.0 and result.trace.t_det == 0
    text = result.to_text()
    assert "rule novelty: N_t ≥ η = 0.000" in text and "max N_t = " in text and "S⁻" not in text
    assert "no failure of this task in the memory to compare with; nearest success frame" in text
    assert result.report is not None and result.report.items == ()
    assert "No failure of this task in the memory" in result.report.to_markdown()


def test_a_memory_with_both_kinds_of_task_judges_each_by_its_own_default(tmp_path: Path) -> None:
    both = write_project_dataset(tmp_path / "both", tasks=("pick_cube",), episodes=4)
    only = write_project_dataset(tmp_path / "only", tasks=("push_cube",), symbols=(), episodes=4)
    manifest = json.loads((both / "manifest.json").read_text(encoding="utf-8"))
    extra = json.loads((only / "manifest.json").read_text(encoding="utf-8"))["episodes"]
    for record in extra:
        (only / record["dir"]).rename(both / record["dir"])
    manifest["episodes"] += extra
    (both / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    memory, _ = build_memory(
        BuildMemoryConfig(
            data=DataSelection(both),
            out=tmp_path / "m",
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=tmp_path / "c"),
            split="train",
        )
    )
    assert memory.tasks == ["pick_cube", "push_cube"] and memory.has_failures("pick_cube")
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "c")
    detector = FailureDetector(memory, encoder, k=2)
    assert detector.rule_for("pick_cube") is CONTRAST and detector.rule_for("push_cube") is NOVELTY
    tests = {t.task: t for t in load_dataset(both).select(split="test")}
    assert detector.run(tests["pick_cube"]).rule is CONTRAST
    assert detector.run(tests["push_cube"]).rule is NOVELTY
    explicit = FailureDetector(memory, encoder, k=2, rule="novelty")  # an explicit rule applies to every task
    assert explicit.run(tests["pick_cube"]).rule is NOVELTY
    with pytest.raises(
        SettingError, match="task 'push_cube' has no failure runs in the memory, so the contrast"
    ):
        FailureDetector(memory, encoder, rule="contrast").run(tests["push_cube"])
    found = calibrate(
        CalibrateConfig(
            data=DataSelection(both),
            memory=tmp_path / "m",
            placement=EncoderPlacement(cache_dir=tmp_path / "c"),
            threshold_policy=ThresholdPolicy(target_fpr=0.5),
        )
    )
    assert None not in (found.delta, found.gamma, found.eta)


@pytest.mark.slow  # an end-to-end run of every verb: the full lane
def test_an_evaluation_grows_from_success_runs_only_to_labelled_failures(tmp_path: Path) -> None:
    from robofailring.evaluation.growth import labelled_failures
    from robofailring.evaluation.job import EvaluateConfig, run_evaluation

    data = write_project_dataset(tmp_path / "data", episodes=4)
    train = load_dataset(data).select(split="train")
    for per_task in (0, 1, 2):
        kept = labelled_failures(train, per_task)
        counts = {
            task: sum(t.is_failure and t.task == task for t in kept) for task in ("pick_cube", "push_cube")
        }
        assert counts == {"pick_cube": per_task, "push_cube": per_task}
        assert sum(not t.is_failure for t in kept) == sum(not t.is_failure for t in train)  # every success
    assert len({t.symbol for t in labelled_failures(train, 2) if t.task == "pick_cube" and t.is_failure}) == 2
    cold = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data),
            threshold_policy=ThresholdPolicy(target_fpr=0.5),
            placement=EncoderPlacement(cache_dir=tmp_path / "c"),
            out=tmp_path / "e0",
            failures_per_task=0,
        )
    )
    assert list(cold.rules) == ["novelty"] and cold.failures == 12
    grown = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data),
            threshold_policy=ThresholdPolicy(target_fpr=0.5),
            placement=EncoderPlacement(cache_dir=tmp_path / "c"),
            out=tmp_path / "e1",
            failures_per_task=1,
        )
    )
    assert list(grown.rules) == ["paper", "contrast", "novelty"]
    entries = FailureMemory.load(tmp_path / "e1" / "memory").entries
    assert len({(e.episode, e.view) for e in entries}) == 2 * 3  # one failure per task, 3 views
    assert len(entries) == 2 * 3 * 5  # dense: frames 1-5 of each (6 frames, all different)
