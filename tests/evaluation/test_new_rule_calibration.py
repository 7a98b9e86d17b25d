"""A rule defined in this file only, registered as rules are, is calibrated by `calibrate`, stored under its
name, read back by `FailureMemory.load`, judges runs and live steps at its stored threshold, is recorded (its
score per view and its threshold line, read back from the `.rrd`) and reviewed: nothing outside the rule's
class names it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import ArrayLike
from rrd import rows, static_value
from synthetic import write_project_dataset

from rfr_viz.jobs.review import ReviewConfig, review
from rfr_viz.paths import REPLAY
from rfr_viz.recordings.replay import record_replay
from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.calibration.conformal import conformal_threshold, empirical_fpr
from robofailring.calibration.job import CalibrateConfig, calibrate
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.detection.rules import RULES, ScoringRule
from robofailring.encoders.placement import EncoderPlacement
from robofailring.evaluation.job import EvaluateConfig, run_evaluation
from robofailring.evaluation.written import write_evaluation
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.recipe import MemoryRecipe

ALPHA = 0.5


class FarFromSuccessRule(ScoringRule):
    """A rule defined only here: S⁺ alone, inverted (fires when nothing in a normal run is near)."""

    name = "far-from-success"
    symbol = "ε"
    score_name = "F_t"
    formula = "F_t = −S⁺_t"
    threshold_key = "epsilon"
    bounds = (-1.0, 1.0)
    default_threshold = -0.5
    needs_successes = True

    def score(self, failure_similarity: ArrayLike, success_similarity: ArrayLike) -> np.ndarray:
        return -np.asarray(success_similarity, dtype=np.float32)


@pytest.fixture
def rule(monkeypatch: pytest.MonkeyPatch) -> ScoringRule:
    """The rule, registered in `RULES` for this test only."""
    registered = FarFromSuccessRule()
    monkeypatch.setitem(RULES, registered.name, registered)
    return registered


def test_a_rule_defined_in_a_test_is_calibrated_stored_reloaded_and_judges(
    rule: ScoringRule, tmp_path: Path
) -> None:
    data = write_project_dataset(tmp_path / "data", episodes=6)
    memory_dir, cache = tmp_path / "memory", tmp_path / "cache"
    build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=memory_dir,
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=cache),
            split="train",
        )
    )

    found = calibrate(
        CalibrateConfig(
            data=DataSelection(data),
            memory=memory_dir,
            placement=EncoderPlacement(cache_dir=cache),
            threshold_policy=ThresholdPolicy(target_fpr=ALPHA),
        )
    )
    assert list(found.thresholds) == ["paper", "contrast", "novelty", rule.name]
    threshold = found.thresholds[rule.name]
    text = found.to_text(memory_dir)
    assert (
        f"ε = {threshold:.6f} (far-from-success rule): FPR {100 * found.achieved_fprs[rule.name]:.1f} %"
        in text
    )

    stored = json.loads((memory_dir / "manifest.json").read_text(encoding="utf-8"))["calibration"]
    assert stored["rules"][rule.name]["threshold"] == threshold
    assert stored["rules"][rule.name]["achieved_fpr"] == found.achieved_fprs[rule.name]
    assert stored["rules"][rule.name]["runs"] == 6  # three training successes per task
    assert stored["rules"][rule.name]["fpr_spread"]["successes"] == 6

    loaded = FailureMemory.load(memory_dir)
    assert loaded.calibrated_threshold(rule.name) == threshold
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    detector = FailureDetector(loaded, encoder, rule=rule.name)
    assert detector.threshold == threshold and detector.uncalibrated == []
    assert FailureDetector(loaded, encoder, thresholds={rule.name: 0.25}).threshold_of(rule) == 0.25

    # the stored threshold is the conformal bound of the training successes' leave-one-out peaks
    successes = [t for t in load_dataset(data).select(split="train") if not t.is_failure]
    peaks = [float(detector.run(t, leave_one_out=True).max_score().max()) for t in successes]
    assert threshold == pytest.approx(conformal_threshold(peaks, ALPHA))
    assert found.achieved_fprs[rule.name] == pytest.approx(empirical_fpr(peaks, threshold))

    trajectory = next(t for t in load_dataset(data).select(split="test") if t.is_failure)
    trace = detector.run(trajectory)
    fused = np.stack([-trace.success_similarity[view] for view in trace.views]).max(axis=0)
    np.testing.assert_array_equal(trace.state, fused >= np.float32(threshold))
    assert trace.to_dict()["thresholds"][rule.name] == threshold == trace.to_dict()["threshold"]
    session = detector.session(trajectory.task)
    for t in range(trace.length):
        step = session.step({view: frames[t] for view, frames in trajectory.views.items()})
        assert step.rule is rule and step.threshold == threshold and step.alarm == bool(trace.state[t])
        assert step.thresholds[rule.name] == threshold
        assert step.rule_scores[rule.name] == pytest.approx(
            {v: float(-trace.success_similarity[v][t]) for v in trace.views}
        )
    assert session.fired_at == trace.t_det

    # recorded: the rule's score of every view and its threshold line, at the paths of its name
    recording = record_replay(trajectory, trace, out=tmp_path / "replay.rrd")
    for view in trace.views:
        logged = rows(recording, REPLAY.score(view, rule.name), "Scalars:scalars")
        np.testing.assert_allclose(
            [value[0] for _, value in logged], -trace.success_similarity[view], atol=1e-6
        )
    line = rows(recording, REPLAY.threshold(rule.name), "Scalars:scalars")
    assert len(line) == trace.length and all(value[0] == pytest.approx(threshold) for _, value in line)
    assert static_value(recording, REPLAY.threshold(rule.name), "SeriesLines:names") == [
        f"ε = {threshold:.3f}"
    ]

    # reviewed: an evaluation reports the rule, and `review --score` replays its false alarms: a failure
    # run added to the test split labelled a success is one
    _add_mislabelled_success(data, trajectory.source)
    evaluated = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data),
            threshold_policy=None,
            memory=memory_dir,
            placement=EncoderPlacement(cache_dir=cache),
            out=tmp_path / "evaluation",
        )
    )
    json_path, _ = write_evaluation(evaluated, tmp_path / "evaluation")
    reported = json.loads(json_path.read_text(encoding="utf-8"))["rules"][rule.name]
    assert reported["threshold"] == threshold and reported["fp"] == 1
    kind = "false-alarms"
    reviewed = review(
        ReviewConfig(
            data=DataSelection(data),
            evaluation=json_path,
            kind=kind,
            out=tmp_path / "review",
            detector=DetectorConfig(rule=rule.name, placement=EncoderPlacement(cache_dir=cache)),
        )
    )
    assert len(reviewed.recordings) == len(reported[kind.replace("-", "_")])
    for path in reviewed.recordings:
        assert rows(path, REPLAY.threshold(rule.name), "Scalars:scalars")[0][1][0] == pytest.approx(threshold)


def _add_mislabelled_success(data: Path, failure: Path | None) -> None:
    """A copy of the failure run at `failure`, added to the dataset's test split as a success."""
    assert failure is not None
    name = "pick_cube_success_episode99"
    shutil.copytree(failure, data / name)
    manifest = json.loads((data / "manifest.json").read_text(encoding="utf-8"))
    record = next(r for r in manifest["episodes"] if r["dir"] == failure.name)
    manifest["episodes"].append(record | {"dir": name, "episode": name, "label": None, "outcome": "success"})
    (data / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
