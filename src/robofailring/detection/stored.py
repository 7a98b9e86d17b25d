"""A memory's stored calibration as the detector uses it: thresholds by rule name, and their time-indexed bands."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from robofailring.detection.band import Band
from robofailring.detection.rules import RULES, ScoringRule, rule_named, rule_of_option
from robofailring.errors import SettingError
from robofailring.memory.failure import FailureMemory
from robofailring.memory.signals.modality import BOTH


def stored_bands(memory: FailureMemory, modality: str = BOTH) -> dict[str, Band]:
    """The time-indexed bands of the memory's stored calibration (for its encoder and `modality`), by
    registered rule name."""
    calibration = memory.manifest.calibration
    if calibration is None or calibration.encoder != memory.encoder or not calibration.judges(modality):
        return {}
    return {
        name: Band.from_dict(stored.band, where=f"the memory's calibration of rule {name!r}")
        for name, stored in calibration.rules.items()
        if name in RULES and stored.band is not None
    }


def stored_threshold(memory: FailureMemory, rule: ScoringRule, modality: str = BOTH) -> float | None:
    """`rule`'s threshold as the memory's calibration stored it for the memory's encoder and `modality`, or None."""
    return memory.calibrated_threshold(rule.name, modality)


def given_thresholds(thresholds: Mapping[str, float] | None, **by_option: float | None) -> dict[str, float]:
    """Thresholds given by rule name, and by each rule's threshold option (`delta=`, `gamma=`, `eta=`: the
    command line's `--delta`, …; None: not given); an unknown rule name or option is a SettingError naming
    the choices, and a rule's threshold given both ways one naming the rule."""
    named = {rule_named(name).name: value for name, value in (thresholds or {}).items()}
    for option, value in by_option.items():
        if value is None:
            continue
        rule = rule_of_option(option)
        if rule.name in named:
            raise SettingError(
                f"the {rule.name} rule's {rule.symbol} is given twice (by name and as a keyword)"
            )
        named[rule.name] = value
    return named


def stored_thresholds(
    memory: FailureMemory, given: Mapping[str, float], modality: str = BOTH
) -> dict[str, float]:
    """Every registered rule's threshold by rule name: `given` (by rule name), else stored (for `modality`),
    else default."""
    thresholds = {}
    for rule in RULES.values():
        value = given.get(rule.name)
        if value is not None:
            rule.check_threshold(value)
        else:
            value = stored_threshold(memory, rule, modality)
        thresholds[rule.name] = float(value if value is not None else rule.default_threshold)
    return thresholds


def uncalibrated_notes(
    memory: FailureMemory, given: Mapping[str, float], used: Iterable[ScoringRule], modality: str = BOTH
) -> list[str]:
    """One sentence per rule in `used` judged at its default threshold: neither given (by rule name) nor
    calibrated for the memory's encoder, so no false-alarm rate is promised for it."""
    notes = []
    for rule in dict.fromkeys(used):
        if rule.name not in given and stored_threshold(memory, rule, modality) is None:
            notes.append(
                f"the {rule.name} rule judges at its default {rule.symbol} = {rule.default_threshold:g}: the "
                "memory is not calibrated for it, so no false-alarm rate is promised (run `robofailring "
                f"calibrate SUCCESS_DATA --memory MEMORY`, or give --{rule.threshold_key})"
            )
    return notes
