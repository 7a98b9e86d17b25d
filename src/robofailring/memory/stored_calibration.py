"""A failure memory's stored thresholds, the manifest's `calibration` section, as typed objects: `StoredCalibration`
(what `robofailring calibrate` chose, paper §IV-C) and one `StoredRule` per rule name. Parsed once when the manifest
is (`robofailring.memory.manifest`); a section written by an older version is read, and unknown keys kept verbatim.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Final

from robofailring.errors import MemoryFormatError
from robofailring.memory.format import is_finite_number, is_number, is_whole
from robofailring.memory.signals.modality import BOTH

# the calibration section's own kinds (its `successes` is a run count, the manifest's the success memory's section)
_CALIBRATION_KINDS: Final[dict[str, Any]] = {
    "modality": lambda v: isinstance(v, str),
    "encoder": lambda v: isinstance(v, str),
    "method": lambda v: isinstance(v, str),
    "target_fpr": is_number,
    "successes": is_whole,
    "data": lambda v: isinstance(v, str),
    "split": lambda v: isinstance(v, str),
    "k": is_whole,
    "stride": is_whole,
}
# one rule's section, `calibration.rules[<rule name>]`
_RULE_KINDS: Final[dict[str, Any]] = {
    "achieved_fpr": is_number,
    "band": lambda v: isinstance(v, dict),
    "fpr_spread": lambda v: isinstance(v, dict),
    "runs": is_whole,
}
# the calibration section before it was keyed by rule name: (rule name, threshold key, its achieved-FPR key)
_LEGACY_RULES: Final[tuple[tuple[str, str, str], ...]] = (
    ("paper", "delta", "achieved_fpr"),
    ("contrast", "gamma", "gamma_achieved_fpr"),
    ("novelty", "eta", "eta_achieved_fpr"),
)
_LEGACY_KEYS: Final[frozenset[str]] = frozenset(
    {key for rule in _LEGACY_RULES for key in rule[1:]} | {"band", "fpr_spread"}
)


@dataclass
class StoredRule:
    """One rule's calibration, `calibration.rules[<rule name>]`: its threshold and how it was set."""

    threshold: float  # the rule's threshold (kept as JSON gave it: an int stays an int)
    achieved_fpr: float | None = None  # share of the calibration runs that reach it
    # its time-indexed band {"kind", "runs", "mean", "scale"} (robofailring.detection.band); None: one number
    band: dict[str, Any] | None = None
    # the realised test FPR's 5–95 % range with these runs (calibration.conformal.FprSpread.to_dict)
    fpr_spread: dict[str, Any] | None = None
    runs: int | None = None  # success runs the threshold was set from
    extra: dict[str, Any] = field(default_factory=dict)  # keys this version does not know, kept verbatim

    @classmethod
    def parse(cls, name: str, section: Any, path: Path) -> StoredRule:
        if not isinstance(section, dict) or not is_finite_number(section.get("threshold")):
            raise MemoryFormatError(
                f"{path}: calibration of rule {name!r} needs a finite 'threshold', not {section!r}; "
                "remove it and run `robofailring calibrate` again"
            )
        typed = {k: v for k, v in section.items() if k in _RULE_KINDS and v is not None and _RULE_KINDS[k](v)}
        extra = {k: v for k, v in section.items() if k != "threshold" and k not in typed and v is not None}
        return cls(threshold=section["threshold"], **typed, extra=extra)

    def to_dict(self) -> dict[str, Any]:
        written = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "extra"}
        return {k: v for k, v in written.items() if v is not None} | self.extra


@dataclass
class StoredCalibration:
    """The manifest's `calibration` section: thresholds chosen by `robofailring calibrate` (paper §IV-C),
    one `StoredRule` per rule name under `rules`, whatever rules are registered.

    A section written before it was keyed by rule name (`delta`, `gamma`, `eta`, their `*achieved_fpr`,
    one `fpr_spread` and one `band` for all) is read into `rules` and written back in this form.
    Numbers are kept as JSON gave them (an int stays an int), so a rewrite gives the same values.
    """

    rules: dict[str, StoredRule]  # by rule name (robofailring.detection.rules)
    encoder: str | None = None  # the encoder identity the thresholds were chosen with
    method: str | None = None
    target_fpr: float | None = None
    successes: int | None = None  # success runs calibrated on
    data: str | None = None
    split: str | None = None
    k: int | None = None
    stride: int | None = None
    # what the thresholds judge: `both` (the cameras and the robot's signals), `cameras` or `signals`; None:
    # calibrated before the choice existed, `both`
    modality: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)  # keys this version does not know, kept verbatim
    absent: frozenset[str] = field(default=frozenset(), repr=False)  # known keys the file did not have

    @classmethod
    def parse(cls, section: Any, path: Path) -> StoredCalibration:
        if not isinstance(section, dict):
            raise MemoryFormatError(
                f"{path}: 'calibration' must be an object with 'rules' and 'encoder', not {section!r}; "
                "remove it and run `robofailring calibrate` again"
            )
        if "rules" in section:
            stored = section["rules"]
            if not isinstance(stored, dict):
                raise MemoryFormatError(f"{path}: calibration 'rules' must be an object, not {stored!r}")
            rules = {name: StoredRule.parse(name, rule, path) for name, rule in stored.items()}
            rest = {k: v for k, v in section.items() if k != "rules"}
        else:
            rules = _legacy_rules(section, path)
            rest = {k: v for k, v in section.items() if k not in _LEGACY_KEYS}
        if not rules:
            raise MemoryFormatError(
                f"{path}: calibration has no rule's threshold; remove it and run `robofailring calibrate` again"
            )
        known = [f.name for f in fields(cls) if f.name not in ("rules", "extra", "absent")]
        typed = {k: rest[k] for k in known if rest.get(k) is not None and _CALIBRATION_KINDS[k](rest[k])}
        extra = {k: v for k, v in rest.items() if k not in typed and not (k in known and v is None)}
        return cls(rules=rules, **typed, extra=extra, absent=frozenset(k for k in known if k not in section))

    def to_dict(self) -> dict[str, Any]:
        written = {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if f.name not in ("rules", "extra", "absent") and f.name not in self.absent
        }
        ordered = {"encoder": written.pop("encoder", None)} if "encoder" in written else {}
        rules = {name: rule.to_dict() for name, rule in self.rules.items()}
        return ordered | written | {"rules": rules} | self.extra

    def threshold_for(self, encoder: str, rule: str, modality: str = BOTH) -> float | None:
        """The threshold of the rule named `rule` when calibrated with `encoder` for `modality` and stored as
        a finite number; otherwise None (also for a rule this section does not have)."""
        stored = self.rules.get(rule)
        if (
            self.encoder == encoder
            and self.judges(modality)
            and stored is not None
            and math.isfinite(stored.threshold)
        ):
            return float(stored.threshold)
        return None

    def judges(self, modality: str) -> bool:
        """Whether the thresholds hold for `modality` (`both`, `cameras` or `signals`): calibrated for it, or
        for `both`, of which either alone is a subset of the views. Every fusion judges the max over views of
        scores each corrected on its own (`robofailring.calibration.fusions`), so leaving views out can only
        lower a run's fused score: the false-alarm rate promised for both still holds for one alone (the
        alarms may come later than thresholds calibrated for it would give: `calibrate --modality`)."""
        calibrated = self.modality or BOTH
        return calibrated in (modality, BOTH)

    def target_for(self, encoder: str) -> float | None:
        """The target false-positive rate α the thresholds were chosen for, if they belong to `encoder`."""
        return (
            float(self.target_fpr) if self.encoder == encoder and isinstance(self.target_fpr, float) else None
        )


def _legacy_rules(section: dict[str, Any], path: Path) -> dict[str, StoredRule]:
    """`rules` from a section written before it was keyed by rule name: δ, γ and η with their achieved
    FPRs; its one `fpr_spread` and run count go to each rule, its `band` section to the rules it names."""
    band = section.get("band")
    bands = band.get("rules") if isinstance(band, dict) else None
    spread = section.get("fpr_spread")
    runs = section.get("successes")
    rules = {}
    for name, key, achieved_key in _LEGACY_RULES:
        threshold = section.get(key)
        if threshold is None:
            continue
        if not is_finite_number(threshold):
            raise MemoryFormatError(f"{path}: calibration {key!r} must be a finite number, not {threshold!r}")
        achieved = section.get(achieved_key)
        fitted = bands.get(name) if isinstance(bands, dict) else None
        rules[name] = StoredRule(
            threshold=threshold,
            achieved_fpr=achieved if is_number(achieved) else None,
            band={"kind": band["kind"], **fitted}
            if isinstance(band, dict) and isinstance(fitted, dict)
            else None,
            fpr_spread=spread if isinstance(spread, dict) else None,
            runs=runs if is_whole(runs) else None,
        )
    return rules
