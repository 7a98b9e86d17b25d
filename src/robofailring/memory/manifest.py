"""A failure memory's `manifest.json` as a typed object: parsed and checked once at load, written by `to_dict`.

Known keys become typed fields; a known key whose value has another type, and every unknown key, is kept
verbatim in `extra`, so a memory written by another version of robofailring loses nothing when rewritten.
`to_dict` gives the same JSON keys and values the manifest was read from (or built with).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Final

from robofailring.data.layouts import PROJECT_FORMAT, detect_layout
from robofailring.errors import DataError, MemoryFormatError
from robofailring.memory.entry import END, FAILURE_FRAMES
from robofailring.memory.format import is_number, is_whole
from robofailring.memory.pairs import CONCAT, PAIRINGS
from robofailring.memory.signals.section import SignalSection
from robofailring.memory.stored_calibration import StoredCalibration

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


# the JSON type each optional key must have to become a typed field (another type stays in `extra`)
_KINDS: Final[dict[str, Any]] = {
    "skipped_views": is_whole,
    "skipped": lambda v: isinstance(v, list),
    "failures": is_whole,
    "ignored_non_failures": is_whole,
    "failure_frames": lambda v: isinstance(v, str),
    "failure_step": is_number,
    "pairing": lambda v: isinstance(v, str),
    "skipped_inputs": lambda v: isinstance(v, list),
    "source": lambda v: isinstance(v, str),
    "layout": lambda v: isinstance(v, str),
    "data_views": lambda v: isinstance(v, list),
    "encoder_spec": lambda v: isinstance(v, str),
    "split": lambda v: isinstance(v, str),
    "data_root": lambda v: isinstance(v, str),
    "vocabulary": lambda v: isinstance(v, str),
    "format_version": is_whole,
    "tasks": lambda v: isinstance(v, dict),
    "views": lambda v: isinstance(v, list),
    "symbols": lambda v: isinstance(v, dict),
    "successes": lambda v: isinstance(v, dict),
    "signals": lambda v: isinstance(v, dict) and bool(v),  # {}: no signal memory, kept in `extra`
    "created": lambda v: isinstance(v, str),
    "encoder": lambda v: isinstance(v, str),
}


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
    signals: SignalSection | None = None  # the signal memory's section (robofailring.memory.signals.section)
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
            if not is_whole(value) or value < 0:
                raise MemoryFormatError(f"{path}: {key!r} must be a whole number ≥ 0, not {value!r}")
        frames, step = manifest.get("failure_frames"), manifest.get("failure_step")
        if frames is not None and frames not in FAILURE_FRAMES:
            readable = " or ".join(FAILURE_FRAMES)
            raise MemoryFormatError(f"{path}: 'failure_frames' is {frames!r}, this version reads {readable}")
        if step is not None and not (is_number(step) and 0.0 <= step <= 2.0):
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
        if "signals" in typed:  # the signal memory's section, read once (its checks: SignalSection.parse)
            typed["signals"] = SignalSection.parse(typed["signals"], path)
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
        if self.signals is not None:
            values["signals"] = self.signals.to_dict()
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
