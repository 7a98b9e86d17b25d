"""A memory's stored calibration as the detector uses it: thresholds by rule, and their time-indexed bands."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from robofailring.detection.band import Band, bands_from_dict
from robofailring.detection.rules import RULES, ScoringRule
from robofailring.memory.failure import FailureMemory


def stored_bands(memory: FailureMemory) -> dict[str, Band]:
    """The time-indexed bands of the memory's stored calibration (for its encoder), by rule name."""
    calibration = memory.manifest.calibration
    if calibration is None or calibration.encoder != memory.encoder or calibration.band is None:
        return {}
    return bands_from_dict(calibration.band, where="the memory's calibration")


def stored_threshold(memory: FailureMemory, rule: ScoringRule) -> float | None:
    """`rule`'s threshold as the memory's calibration stored it for the memory's encoder, or None."""
    calibration = memory.manifest.calibration
    return calibration.threshold_for(memory.encoder, rule.threshold_key) if calibration is not None else None


def stored_thresholds(memory: FailureMemory, given: Mapping[str, float | None]) -> dict[str, float]:
    """Every registered rule's threshold by name: `given` (by its threshold key), else stored, else default."""
    thresholds = {}
    for rule in RULES.values():
        value = given.get(rule.threshold_key)
        if value is not None:
            rule.check_threshold(value)
        else:
            value = stored_threshold(memory, rule)
        thresholds[rule.name] = float(value if value is not None else rule.default_threshold)
    return thresholds


def uncalibrated_notes(
    memory: FailureMemory, given: Mapping[str, float | None], used: Iterable[ScoringRule]
) -> list[str]:
    """One sentence per rule in `used` judged at its default threshold: neither given (by its threshold
    key) nor calibrated for the memory's encoder, so no false-alarm rate is promised for it."""
    notes = []
    for rule in dict.fromkeys(used):
        if given.get(rule.threshold_key) is None and stored_threshold(memory, rule) is None:
            notes.append(
                f"the {rule.name} rule judges at its default {rule.symbol} = {rule.default_threshold:g}: the "
                "memory is not calibrated for it, so no false-alarm rate is promised (run `robofailring "
                f"calibrate SUCCESS_DATA --memory MEMORY`, or give --{rule.threshold_key})"
            )
    return notes
