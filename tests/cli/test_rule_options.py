"""A scoring rule's threshold option comes from the rule (docs/rules.md, "Adding a rule"): a rule registered in
`RULES` before the command line is built gets `--<threshold_key>` with its help on every verb that judges, and
the value given there reaches the detector as the rule's threshold."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from fault_helpers import cli

from robofailring.cli.option_groups import DETECTOR, RULE_CHOICE, RULE_THRESHOLDS
from robofailring.detection.rules import RULES, ScoringRule
from robofailring.detection.stored import given_thresholds
from robofailring.errors import SettingError

#: A rule defined nowhere else (its threshold option `--epsilon`).
RULE_SOURCE = """
import numpy as np
from robofailring.detection.rules import ScoringRule

class FarRule(ScoringRule):
    name = "far"
    symbol = "ε"
    score_name = "F_t"
    formula = "F_t = −S⁻_t"
    threshold_key = "epsilon"
    threshold_title = "Far threshold"
    bounds = (-1.0, 1.0)
    default_threshold = -0.5
    needs_successes = False

    def score(self, failure_similarity, success_similarity):
        return -np.asarray(failure_similarity, dtype=np.float32)
"""
#: A fresh interpreter that registers the rule, then runs the command line.
WITH_A_NEW_RULE = (
    RULE_SOURCE
    + """
import sys
from robofailring.detection.rules import RULES
RULES[FarRule.name] = FarRule()
from rfr_viz.cli.app import main
sys.argv = ["robofailring", *sys.argv[1:]]
main()
"""
)


def _far_rule() -> ScoringRule:
    defined: dict[str, Any] = {}
    exec(RULE_SOURCE, defined)  # the very rule the fresh interpreter registers
    rule: ScoringRule = defined["FarRule"]()
    return rule


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", WITH_A_NEW_RULE, *map(str, args)],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "300"},  # one line per option
    )


def test_the_detector_group_offers_each_registered_rules_threshold() -> None:
    assert RULE_THRESHOLDS == ("delta", "gamma", "eta")
    assert RULE_CHOICE == ("score", "delta", "gamma", "eta")
    offered = {parameter.name: parameter for parameter in DETECTOR.parameters()}
    for rule in RULES.values():
        option = offered[rule.threshold_key].annotation.__metadata__[0]
        assert (option.help, option.show_default) == (rule.threshold_help, rule.threshold_default)
    assert RULES["contrast"].threshold_help == "Contrast threshold γ."
    assert RULES["contrast"].threshold_default == "the memory's calibrated γ, else 0"
    assert DETECTOR.value({"delta": 0.5, "eta": None}).thresholds == {"paper": 0.5}


def test_thresholds_given_by_option_go_to_the_rule_of_that_option(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(RULES, "far", _far_rule())
    assert given_thresholds({"contrast": 0.1}, epsilon=0.3, delta=None) == {"contrast": 0.1, "far": 0.3}
    with pytest.raises(SettingError, match=r"the far rule's ε is given twice"):
        given_thresholds({"far": 0.2}, epsilon=0.3)
    with pytest.raises(SettingError, match=r"no scoring rule has the threshold option --zeta; .*--epsilon"):
        given_thresholds(None, zeta=0.3)


def test_a_new_rule_gets_its_option_on_the_command_line(
    data: Path, built_memory: Path, cache: list[str]
) -> None:
    shown = _run("detect", "--help")
    assert shown.returncode == 0, shown.stderr
    help_text = " ".join(shown.stdout.split())
    assert (
        "--epsilon" in help_text
        and "Far threshold ε. [default: (the memory's calibrated ε, else -0.5)]" in help_text
    )
    episode = next(path for path in sorted(data.iterdir()) if path.is_dir())
    judged = _run(
        "detect", episode, "--memory", built_memory, "--score", "far", "--epsilon", "-0.25", "--json", *cache
    )
    assert judged.returncode == 0, judged.stderr
    trace = json.loads(judged.stdout)
    assert (trace["score"], trace["threshold"], trace["thresholds"]["far"]) == ("far", -0.25, -0.25)
    assert trace["thresholds"]["paper"] == RULES["paper"].default_threshold
    triage = _run("triage", "--help")  # triage judges by the memory's own thresholds: no rule's option
    assert triage.returncode == 0 and "--epsilon" not in triage.stdout and "--delta" not in triage.stdout
    assert cli("detect", "--help").exit_code == 0  # this interpreter's command line is untouched
