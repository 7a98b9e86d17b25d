"""A failure memory's `manifest.json` as a typed object: parsed and checked once at load, written by `to_dict`.

Known keys become typed fields; a known key whose value has another type, and every unknown key, is kept
verbatim in `extra`, so a memory written by another version of robofailring loses nothing when rewritten.
`to_dict` gives the same JSON keys and values the manifest was read from (or built with).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Final

from robofailring.data.layouts import PROJECT_FORMAT, detect_layout
from robofailring.errors import DataError, MemoryFormatError
from robofailring.memory.entry import END, FAILURE_FRAMES
from robofailring.memory.pairs import CONCAT, PAIRINGS
from robofailring.memory.signals.modality import BOTH

# the order keys are written in: that of a memory built by `build-memory` and then calibrated
_ORDER: Final[tuple[str, ...]] = (
    "dim",
    "skipped_views",
    "skipped",
    "failures",
    "ignored_non_failures",
    "failure_frames",
    "failure_step",
    "pairing",
    "skipped_inputs",
    "source",
    "layout",
    "data_views",
    "encoder_spec",
    "split",
    "data_root",
    "vocabulary",
    "format_version",
    "encoder",
    "count",
    "tasks",
    "views",
    "symbols",
    "successes",
    "signals",
    "created",
    "calibration",
)


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _finite(value: Any) -> bool:
    return _number(value) and math.isfinite(value)


def _whole(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


# the JSON type each optional key must have to become a typed field (another type stays in `extra`)
_KINDS: Final[dict[str, Any]] = {
    "skipped_views": _whole,
    "skipped": lambda v: isinstance(v, list),
    "failures": _whole,
    "ignored_non_failures": _whole,
    "failure_frames": lambda v: isinstance(v, str),
    "failure_step": _number,
    "pairing": lambda v: isinstance(v, str),
    "skipped_inputs": lambda v: isinstance(v, list),
    "source": lambda v: isinstance(v, str),
    "layout": lambda v: isinstance(v, str),
    "data_views": lambda v: isinstance(v, list),
    "encoder_spec": lambda v: isinstance(v, str),
    "split": lambda v: isinstance(v, str),
    "data_root": lambda v: isinstance(v, str),
    "vocabulary": lambda v: isinstance(v, str),
    "format_version": _whole,
    "tasks": lambda v: isinstance(v, dict),
    "views": lambda v: isinstance(v, list),
    "symbols": lambda v: isinstance(v, dict),
    "successes": lambda v: isinstance(v, dict),
    "signals": lambda v: isinstance(v, dict),
    "created": lambda v: isinstance(v, str),
    "encoder": lambda v: isinstance(v, str),
}
# the calibration section's own kinds (its `successes` is a run count, the manifest's the success memory's section)
_CALIBRATION_KINDS: Final[dict[str, Any]] = {
    "modality": lambda v: isinstance(v, str),
    "encoder": lambda v: isinstance(v, str),
    "method": lambda v: isinstance(v, str),
    "target_fpr": _number,
    "successes": _whole,
    "data": lambda v: isinstance(v, str),
    "split": lambda v: isinstance(v, str),
    "k": _whole,
    "stride": _whole,
}
# one rule's section, `calibration.rules[<rule name>]`
_RULE_KINDS: Final[dict[str, Any]] = {
    "achieved_fpr": _number,
    "band": lambda v: isinstance(v, dict),
    "fpr_spread": lambda v: isinstance(v, dict),
    "runs": _whole,
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
        if not isinstance(section, dict) or not _finite(section.get("threshold")):
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
        if not _finite(threshold):
            raise MemoryFormatError(f"{path}: calibration {key!r} must be a finite number, not {threshold!r}")
        achieved = section.get(achieved_key)
        fitted = bands.get(name) if isinstance(bands, dict) else None
        rules[name] = StoredRule(
            threshold=threshold,
            achieved_fpr=achieved if _number(achieved) else None,
            band={"kind": band["kind"], **fitted}
            if isinstance(band, dict) and isinstance(fitted, dict)
            else None,
            fpr_spread=spread if isinstance(spread, dict) else None,
            runs=runs if _whole(runs) else None,
        )
    return rules


@dataclass
class MemoryManifest:
    """What `manifest.json` says about a failure memory: its encoder, size, provenance and calibration."""

    encoder: str  # the encoder identity the vectors were made with
    dim: int
    count: int = 0  # memory entries (written from the entries at save)
    format_version: int | None = None
    tasks: dict[str, int] | None = None  # entries per task
    views: list[str] | None = None
    symbols: dict[str, int] | None = None  # entries per failure symbol
    data_root: str | None = None  # absolute root the entries' references are stored relative to
    vocabulary: str | None = None  # the memory's own symbols beyond Table 5: that file in its folder
    source: str | None = None  # the dataset the memory was built from
    layout: str | None = None  # that dataset's layout
    data_views: list[str] | None = None  # the views read from it (after `--views`)
    split: str | None = None  # the split the memory was built from
    encoder_spec: str | None = None  # the spec that opens the encoder again (`--encoder`)
    skipped_inputs: list[dict[str, Any]] | None = (
        None  # listed by its builds: not read, blank, signals not used
    )
    skipped_views: int | None = None  # failure views with too few frames
    skipped: list[dict[str, Any]] | None = None  # those views
    failures: int | None = None
    ignored_non_failures: int | None = None
    failure_frames: str | None = (
        None  # "end" or "dense" (robofailring.memory.entry); None: built before, "end"
    )
    failure_step: float | None = None  # a dense memory's thinning step of its failure frames
    pairing: str | None = (
        None  # "concat" or "change" (robofailring.memory.pairs); None: built before, "concat"
    )
    successes: dict[str, Any] | None = None  # the success memory's section (robofailring.memory.success)
    signals: dict[str, Any] | None = None  # the signal memory's section (robofailring.memory.signals.memory)
    created: str | None = None
    calibration: StoredCalibration | None = None
    extra: dict[str, Any] = field(default_factory=dict)  # keys this version does not know, kept verbatim

    @classmethod
    def parse(cls, manifest: Any, path: Path) -> MemoryManifest:
        """The manifest read from `path`, or MemoryFormatError naming the field that is wrong."""
        if isinstance(manifest, dict) and manifest.get("format") == PROJECT_FORMAT:
            raise not_a_memory(path.parent)
        if not isinstance(manifest, dict):
            raise MemoryFormatError(
                f"{path} holds a JSON {type(manifest).__name__}, not a memory manifest object"
            )
        for key in ("encoder", "dim", "count"):
            if key not in manifest:
                raise MemoryFormatError(f"{path} lacks {key!r}")
        if not isinstance(manifest["encoder"], str):
            raise MemoryFormatError(f"{path}: 'encoder' must be a string, not {manifest['encoder']!r}")
        for key in ("dim", "count"):
            value = manifest[key]
            if not _whole(value) or value < 0:
                raise MemoryFormatError(f"{path}: {key!r} must be a whole number ≥ 0, not {value!r}")
        frames, step = manifest.get("failure_frames"), manifest.get("failure_step")
        if frames is not None and frames not in FAILURE_FRAMES:
            readable = " or ".join(FAILURE_FRAMES)
            raise MemoryFormatError(f"{path}: 'failure_frames' is {frames!r}, this version reads {readable}")
        if step is not None and not (_number(step) and 0.0 <= step <= 2.0):
            raise MemoryFormatError(
                f"{path}: 'failure_step' must be a cosine step within [0, 2], not {step!r}"
            )
        pairing = manifest.get("pairing")
        if pairing is not None and pairing not in PAIRINGS:
            raise MemoryFormatError(
                f"{path}: 'pairing' is {pairing!r}, this version reads {' or '.join(PAIRINGS)}"
            )
        calibration = manifest.get("calibration")
        parsed = StoredCalibration.parse(calibration, path) if calibration is not None else None
        optional = [
            f.name for f in fields(cls) if f.name not in ("encoder", "dim", "count", "calibration", "extra")
        ]
        typed = {k: manifest[k] for k in optional if k in manifest and _KINDS[k](manifest[k])}
        fixed = {"encoder", "dim", "count", "calibration", *typed}
        extra = {k: v for k, v in manifest.items() if k not in fixed}
        if calibration is None and "calibration" in manifest:
            extra["calibration"] = None
        return cls(
            encoder=manifest["encoder"],
            dim=manifest["dim"],
            count=manifest["count"],
            calibration=parsed,
            **typed,
            extra=extra,
        )

    @property
    def failure_mode(self) -> str:
        """The failure frames the memory holds: `end` (the paper's; also every memory built before the
        choice existed) or `dense`."""
        return self.failure_frames or END

    @property
    def pairing_mode(self) -> str:
        """How the memory pairs a first and a current frame: `concat` (the paper's; also every memory built
        before the choice existed) or `change`."""
        return self.pairing or CONCAT

    def to_dict(self) -> dict[str, Any]:
        """The manifest as JSON: typed fields that are set, then `extra`, in the order build writes them."""
        values: dict[str, Any] = {
            f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("extra", "calibration")
        }
        if self.calibration is not None:
            values["calibration"] = self.calibration.to_dict()
        values = {k: v for k, v in values.items() if v is not None} | self.extra
        return {k: values[k] for k in _ORDER if k in values} | {
            k: v for k, v in values.items() if k not in _ORDER
        }


def not_a_memory(directory: Path) -> MemoryFormatError:
    """The error for a folder given as a memory that is none: a dataset of any layout is named as one,
    with how to build a memory from it (`--memory` pointed at the data is a newcomer's first slip)."""
    try:
        layout = detect_layout(directory)
    except (DataError, OSError):
        return MemoryFormatError(f"{directory} is not a failure memory: manifest.json is missing")
    return MemoryFormatError(
        f"{directory} is a dataset ({layout} layout), not a memory; build one with "
        f"`robofailring build-memory {directory} --out MEMORY` and pass that folder as --memory"
    )
