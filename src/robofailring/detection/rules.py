"""Scoring rules: which score the detector thresholds, each rule one class behind one interface.

`paper` is the rule of paper §3.3 (eq. 6–7): S⁻_t ≥ δ. `contrast` is this project's addition
(docs/rules.md, "Success contrast"): the same query is also matched against the task's success runs, and
the alarm needs the current state to be nearer a failure's end than anything seen in a normal run,
C_t = S⁻_t − S⁺_t ≥ γ. `novelty` needs no failure at all (docs/rules.md, "Success runs only"): how far
the current pair is from anything seen in the task's success runs, N_t = 1 − S⁺_t ≥ η. Every
threshold is set by split-conformal calibration (`robofailring.calibration.conformal`).

A new rule is one `ScoringRule` subclass added to `RULES`: the detector, its trace, the live step,
the evaluation, the CLI's `--score` and its threshold option `--<threshold_key>` (`threshold_keys`), and the
recordings all ask the rule object, and `calibrate` stores its threshold under its `name`
(`calibration.rules.<name>` in a memory's manifest; docs/rules.md, "Adding a rule").
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable
from typing import ClassVar, Final

import numpy as np
from numpy.typing import ArrayLike

from robofailring.errors import SettingError


class ScoringRule(ABC):
    """One scoring rule: the score it computes from S⁻ and S⁺, and the threshold it is judged against."""

    name: ClassVar[str]  # written into JSON, manifests and recordings, and `--score`'s choices
    symbol: ClassVar[str]  # the threshold's symbol, e.g. δ
    score_name: ClassVar[str]  # the score's symbol, e.g. S_t
    formula: ClassVar[str]  # what the score is, for help texts
    threshold_key: ClassVar[str]  # the threshold's option name (`--delta`); thresholds are stored by `name`
    threshold_title: ClassVar[str] = "Threshold"  # its option's help: "Contrast threshold γ."
    bounds: ClassVar[tuple[float, float]]  # the valid threshold range
    default_threshold: ClassVar[float]  # used until a memory is calibrated
    needs_successes: ClassVar[bool]  # the score needs S⁺, so a memory with success runs
    needs_failures: ClassVar[bool] = True  # the score needs S⁻, so failure entries of the task
    shown_beside: ClassVar[bool] = True  # plotted in recordings beside the rule that judges, not only as it

    @abstractmethod
    def score(self, failure_similarity: ArrayLike, success_similarity: ArrayLike) -> np.ndarray:
        """The rule's score from S⁻ and S⁺ (scalars or arrays alike); NaN where it cannot be scored."""

    def check_threshold(self, value: float) -> float:
        """`value` when it lies in the rule's range; SettingError otherwise (NaN too)."""
        low, high = self.bounds
        if not low <= value <= high:
            raise SettingError(
                f"{self.symbol} must lie in [{low:g}, {high:g}] for the {self.name} rule, got {value}"
            )
        return value

    @property
    def threshold_help(self) -> str:
        """The help of the rule's threshold option (`--<threshold_key>`); its default is `threshold_default`."""
        return f"{self.threshold_title} {self.symbol}."

    @property
    def threshold_default(self) -> str:
        """What the threshold option's default is, in `--help`'s one way of showing defaults."""
        return f"the memory's calibrated {self.symbol}, else {self.default_threshold:g}"

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __str__(self) -> str:
        return self.name


class PaperRule(ScoringRule):
    """The paper's rule (§3.3, eq. 6–7): fire when S⁻_t, the nearest failure end's similarity, reaches δ."""

    name = "paper"
    symbol = "δ"
    score_name = "S_t"
    formula = "S_t"
    threshold_key = "delta"
    bounds = (-1.0, 1.0)  # a cosine similarity
    default_threshold = 0.92  # the paper's δ (§4)
    needs_successes = False

    def score(self, failure_similarity: ArrayLike, success_similarity: ArrayLike) -> np.ndarray:
        return np.asarray(failure_similarity, dtype=np.float32)


class ContrastRule(ScoringRule):
    """Success contrast: fire when C_t = S⁻_t − S⁺_t reaches γ (nearer a failure's end than any success frame)."""

    name = "contrast"
    symbol = "γ"
    score_name = "C_t"
    formula = "C_t = S⁻_t − S⁺_t"
    threshold_key = "gamma"
    threshold_title = "Contrast threshold"
    bounds = (-2.0, 2.0)  # a difference of two cosines
    default_threshold = 0.0
    needs_successes = True

    def score(self, failure_similarity: ArrayLike, success_similarity: ArrayLike) -> np.ndarray:
        return np.asarray(failure_similarity, dtype=np.float32) - np.asarray(
            success_similarity, dtype=np.float32
        )


class NoveltyRule(ScoringRule):
    """Success novelty: fire when N_t = 1 − S⁺_t reaches η (far from every success frame of the task).

    It needs no failure run, so it judges a task whose memory holds success runs only; it cannot
    say which failure a run looks like (the neighbour panel says there is none to show)."""

    name = "novelty"
    symbol = "η"
    score_name = "N_t"
    formula = "N_t = 1 − S⁺_t"
    threshold_key = "eta"
    threshold_title = "Novelty threshold"
    bounds = (0.0, 2.0)  # one minus a cosine
    default_threshold = 0.1
    needs_successes = True
    needs_failures = False
    shown_beside = False  # the judge of tasks without failures: plotted only where it judges

    def score(self, failure_similarity: ArrayLike, success_similarity: ArrayLike) -> np.ndarray:
        return np.asarray(1.0 - np.asarray(success_similarity, dtype=np.float32), dtype=np.float32)


PAPER: Final[ScoringRule] = PaperRule()
CONTRAST: Final[ScoringRule] = ContrastRule()
NOVELTY: Final[ScoringRule] = NoveltyRule()
RULES: Final[dict[str, ScoringRule]] = {rule.name: rule for rule in (PAPER, CONTRAST, NOVELTY)}
PAPER_DELTA: Final[float] = PaperRule.default_threshold  # the paper's default δ (§4)


def rule_named(name: str | ScoringRule) -> ScoringRule:
    """The registered rule of this name (a rule is returned as it is); SettingError naming the choices."""
    if isinstance(name, ScoringRule):
        return name
    try:
        return RULES[name]
    except KeyError:
        raise SettingError(f"unknown scoring rule {name!r}; choose one of {list(RULES)}") from None


def rule_of_option(threshold_key: str) -> ScoringRule:
    """The registered rule whose threshold option is `--<threshold_key>`; SettingError naming the options."""
    for rule in RULES.values():
        if rule.threshold_key == threshold_key:
            return rule
    options = ", ".join(f"--{rule.threshold_key}" for rule in RULES.values())
    raise SettingError(
        f"no scoring rule has the threshold option --{threshold_key}; the options are {options}"
    )


def threshold_keys() -> tuple[str, ...]:
    """Each registered rule's threshold option name (`delta`, …), in registry order: the command line's options."""
    return tuple(rule.threshold_key for rule in RULES.values())


def rules_for(*, successes: bool, failures: bool = True) -> list[ScoringRule]:
    """The registered rules a memory (or one task of it) supports: those needing S⁺ only with success
    runs, those needing S⁻ only with failure entries."""
    return [
        rule
        for rule in RULES.values()
        if (successes or not rule.needs_successes) and (failures or not rule.needs_failures)
    ]


def shown_rules(judging: ScoringRule, *, successes: bool, failures: bool = True) -> list[ScoringRule]:
    """The rules whose scores and thresholds recordings and reports show, in registry order: every rule a
    task supports (`rules_for`) that is shown beside the judging rule, and the judging rule itself."""
    return [
        rule
        for rule in rules_for(successes=successes, failures=failures)
        if rule.shown_beside or rule.name == judging.name
    ]


def default_rule(*, successes: bool, failures: bool = True) -> ScoringRule:
    """The rule a task is judged by when none is chosen: `contrast` with both success runs and
    failure entries, `novelty` with success runs only, the paper's rule with failures only."""
    if successes:
        return CONTRAST if failures else NOVELTY
    return PAPER


def reported_default(names: Iterable[str]) -> ScoringRule:
    """The rule a detector on an evaluated memory judges by by default (`default_rule`), from the rules the
    evaluation reports (its JSON's `rules`): one needing S⁺ means success runs, one needing S⁻ failure
    entries; the paper rule for an evaluation written before every rule was reported."""
    reported = [RULES[name] for name in names if name in RULES]
    if not reported:
        return PAPER
    return default_rule(
        successes=any(rule.needs_successes for rule in reported),
        failures=any(rule.needs_failures for rule in reported),
    )


class RuleThresholds:
    """Each rule's threshold by rule name (`thresholds`), for the detector and its traces alike."""

    thresholds: dict[str, float]

    def threshold_of(self, rule: ScoringRule) -> float:
        """Any rule's threshold as held here (its default where none was set)."""
        return self.thresholds.get(rule.name, rule.default_threshold)

    @property
    def delta(self) -> float:
        """The paper rule's δ."""
        return self.threshold_of(PAPER)

    @property
    def gamma(self) -> float:
        """The contrast rule's γ."""
        return self.threshold_of(CONTRAST)

    @property
    def eta(self) -> float:
        """The novelty rule's η."""
        return self.threshold_of(NOVELTY)
