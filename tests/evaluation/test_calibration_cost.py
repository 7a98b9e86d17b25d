"""Calibration that spends its runs (issue 51 item 5): each rule's row gives the best recall any threshold reaches at
its test FPR (what calibration cost), a calibration that can only take its highest success peak says so with the
runs that would not, and the demo simulates enough successes for its α."""

from __future__ import annotations

import math

import pytest

from rfr_viz.jobs.demo import DemoConfig, demo_successes
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.evaluation.per_rule import best_recall, runs_below_top, top_peak_text


def test_the_best_recall_at_a_test_fpr_allows_as_many_false_alarms_as_it() -> None:
    failures = [0.9, 0.8, 0.5, 0.3, 0.1]
    successes = [0.6, 0.4, 0.2, 0.05]
    assert best_recall(failures, successes, 0.0) == pytest.approx(2 / 5)  # above 0.6: 0.9, 0.8
    assert best_recall(failures, successes, 0.25) == pytest.approx(3 / 5)  # one alarm allowed: above 0.4
    assert best_recall(failures, successes, 0.5) == pytest.approx(4 / 5)
    assert best_recall(failures, successes, 1.0) == 1.0
    assert best_recall([0.6], [0.6], 0.0) == 0.0  # a tie fires the success too
    assert math.isnan(best_recall([], successes, 0.0))


def test_a_calibration_that_can_only_take_its_highest_peak_says_how_many_runs_would_not() -> None:
    # split conformal at α takes the ⌈(n+1)(1−α)⌉-th smallest of n peaks: below the highest from 39 runs at 5 %
    assert runs_below_top(0.05) == 39 and runs_below_top(0.2) == 9
    assert math.ceil(39 * 0.95) == 38 and math.ceil(40 * 0.95) == 38
    said = top_peak_text(20, 0.05)
    assert "with 20 runs the threshold is the highest calibration peak" in said and "39 runs" in said
    assert top_peak_text(39, 0.05) == "" and top_peak_text(10, 0.05) == ""  # enough; too few (said elsewhere)


def test_the_demo_simulates_enough_successes_for_its_alpha() -> None:
    default = DemoConfig()
    per_task = demo_successes(default)
    assert per_task == 20 and per_task // 2 * len(default.tasks) >= runs_below_top(0.05)
    assert demo_successes(DemoConfig(threshold_policy=ThresholdPolicy(0.1))) == math.ceil(
        2 * runs_below_top(0.1) / 4
    )
    assert demo_successes(DemoConfig(success_episodes=4)) == 4
