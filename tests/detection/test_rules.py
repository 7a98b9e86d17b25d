"""Scoring rules: each is one class behind one interface, and a new one needs nothing but its class."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.typing import ArrayLike
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.calibration.job import available_rules
from robofailring.cli.detector_options import ScoreOption
from robofailring.data.selection import DataSelection
from robofailring.detection.rules import (
    CONTRAST,
    NOVELTY,
    PAPER,
    RULES,
    ContrastRule,
    PaperRule,
    ScoringRule,
    rule_named,
    rules_for,
)
from robofailring.detection.view_scores import reaches
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import SettingError
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.recipe import MemoryRecipe

NAN = float("nan")


def test_the_paper_rule_scores_s_minus_against_delta() -> None:
    assert isinstance(PAPER, PaperRule) and rule_named("paper") is PAPER
    assert (PAPER.name, PAPER.symbol, PAPER.score_name, PAPER.threshold_key) == ("paper", "δ", "S_t", "delta")
    assert PAPER.bounds == (-1.0, 1.0) and PAPER.default_threshold == 0.92 and not PAPER.needs_successes
    assert float(PAPER.score(0.7, 0.9)) == pytest.approx(0.7)  # S⁺ plays no part
    np.testing.assert_array_equal(PAPER.score([0.5, NAN], [NAN, 0.1]), np.float32([0.5, NAN]))
    np.testing.assert_array_equal(
        reaches(PAPER.score([0.5, NAN, 0.95], [0, 0, 0]), 0.9), [False, False, True]
    )
    assert PAPER.check_threshold(-1.0) == -1.0
    for bad in (1.01, -1.5, NAN):
        with pytest.raises(SettingError, match=r"δ must lie in \[-1, 1\] for the paper rule"):
            PAPER.check_threshold(bad)


def test_the_contrast_rule_scores_s_minus_minus_s_plus_against_gamma() -> None:
    assert isinstance(CONTRAST, ContrastRule) and rule_named("contrast") is CONTRAST
    assert (CONTRAST.name, CONTRAST.symbol, CONTRAST.score_name) == ("contrast", "γ", "C_t")
    assert CONTRAST.bounds == (-2.0, 2.0) and CONTRAST.default_threshold == 0.0 and CONTRAST.needs_successes
    assert float(CONTRAST.score(0.9, 0.6)) == pytest.approx(0.3)
    scores = CONTRAST.score(np.float32([0.9, 0.5, NAN]), np.float32([0.6, NAN, 0.2]))
    np.testing.assert_allclose(scores, [0.3, NAN, NAN], atol=1e-7)
    np.testing.assert_array_equal(reaches(scores, -2.0), [True, False, False])  # NaN never fires
    assert CONTRAST.check_threshold(1.5) == 1.5
    with pytest.raises(SettingError, match=r"γ must lie in \[-2, 2\] for the contrast rule"):
        CONTRAST.check_threshold(2.5)


def test_the_registry_names_the_rules_everywhere() -> None:
    assert list(RULES) == ["paper", "contrast", "novelty"]
    assert rules_for(successes=False) == [PAPER] and rules_for(successes=True) == [PAPER, CONTRAST, NOVELTY]
    assert rule_named(CONTRAST) is CONTRAST and str(CONTRAST) == "contrast"
    with pytest.raises(
        SettingError, match=r"unknown scoring rule 'both'; choose one of \['paper', 'contrast', 'novelty'\]"
    ):
        rule_named("both")
    help_text = ScoreOption.__metadata__[0].help
    assert "`paper` (S_t ≥ δ)" in help_text and "`contrast` (C_t = S⁻_t − S⁺_t ≥ γ)" in help_text
    assert "`novelty` (N_t = 1 − S⁺_t ≥ η)" in help_text


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


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, FailureMemory, CachedEncoder]:
    folder = tmp_path_factory.mktemp("rules")
    data = write_project_dataset(folder / "data", episodes=6)
    memory, _ = build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=folder / "memory",
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=folder / "cache"),
            split="train",
        )
    )
    return data, memory, CachedEncoder(load_encoder("pixels"), cache_dir=folder / "cache")


def test_a_new_rule_is_one_class(
    built: tuple[Path, FailureMemory, CachedEncoder], monkeypatch: pytest.MonkeyPatch
) -> None:
    data, memory, encoder = built
    rule = FarFromSuccessRule()
    monkeypatch.setitem(RULES, rule.name, rule)
    trajectory = next(t for t in load_dataset(data).select(split="test") if t.is_failure)
    plain = FailureDetector(memory, encoder, k=2, rule="paper").run(trajectory)
    expected = {view: -plain.success_similarity[view] for view in plain.views}
    fused = np.stack(list(expected.values())).max(axis=0)
    threshold = float(np.median(fused))  # fires part-way through the run
    monkeypatch.setattr(FarFromSuccessRule, "default_threshold", threshold)
    t_det = int(np.flatnonzero(fused >= np.float32(threshold))[0])
    strongest = max(plain.views, key=lambda view: float(expected[view][t_det]))

    detector = FailureDetector(memory, encoder, k=2, rule=rule.name)
    assert detector.rule is rule and detector.threshold == threshold and rule in available_rules(detector)
    trace = detector.run(trajectory)
    for view in trace.views:
        np.testing.assert_array_equal(trace.scores[view], expected[view])
    np.testing.assert_array_equal(trace.state, fused >= np.float32(threshold))
    assert trace.t_det == t_det and trace.detected_view == strongest
    found = trace.to_dict()
    assert (found["score"], found["threshold"], found["t_det"]) == ("far-from-success", threshold, t_det)
    assert found["detected_view"] == strongest and found["delta"] == plain.delta  # δ still beside it

    session = detector.session(trajectory.task)
    for t in range(trace.length):
        step = session.step({view: frames[t] for view, frames in trajectory.views.items()})
        assert step.rule is rule and step.threshold == threshold
        assert step.score == pytest.approx({view: float(expected[view][t]) for view in trace.views})
        assert step.alarm == step.state == bool(trace.state[t])
        firing = [view for view in trace.views if expected[view][t] >= np.float32(threshold)]
        assert step.fired_views == firing
        assert step.detected_view == (max(firing, key=lambda view: step.score[view]) if firing else None)
    assert session.fired_at == t_det

    successes, memory.successes = memory.successes, None  # a memory built without success runs
    try:
        with pytest.raises(SettingError, match="the far-from-success rule needs success runs"):
            FailureDetector(memory, encoder, rule=rule.name)
    finally:
        memory.successes = successes
