"""The detector's settings, checked where they are given: `Scoring`, how runs are scored (K neighbours per query,
the modality judged by), and `DetectorConfig`, what opens a detector (the memory, its encoder and data root, the
rule and thresholds that decide) composed of its `Scoring` and its encoder's `EncoderPlacement`; the stride."""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Final

from robofailring.detection.rules import rule_named
from robofailring.encoders.placement import DEFAULT_PLACEMENT, EncoderPlacement
from robofailring.errors import SettingError
from robofailring.memory.signals.modality import BOTH, MODALITIES

DEFAULT_K: Final[int] = 5
DEFAULT_MODALITY: Final[str] = (
    BOTH  # what a detector judges by unless told: the cameras and the signals fused
)
DEFAULT_STRIDE: Final[int] = 1  # every frame scored
MAX_STRIDE: Final[int] = 2**63 - 1  # frame numbers are int64: a larger stride scores frame 0 alone anyway
MAX_K: Final[int] = (
    1024  # neighbours per query: each query row holds K similarities, allocated before the search
)


def _whole_number(value: object) -> bool:
    """An int (or numpy integer) that is not a bool: what Faiss and slicing take as a count."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_k(k: int) -> int:
    """K, the neighbours retrieved per query: a whole number from 1 to `MAX_K` (SettingError otherwise)."""
    if not _whole_number(k) or not 1 <= k <= MAX_K:
        raise SettingError(f"k (neighbours per query) must be a whole number from 1 to {MAX_K}, got {k}")
    return k


def check_modality(modality: str) -> str:
    """`both`, `cameras` or `signals` (SettingError naming them otherwise)."""
    if modality not in MODALITIES:
        raise SettingError(f"--modality must be one of {', '.join(MODALITIES)}, got {modality!r}")
    return modality


def check_stride(stride: int) -> int:
    """The scoring stride: a whole number from 1 to `MAX_STRIDE` (SettingError otherwise)."""
    if not _whole_number(stride) or not 1 <= stride <= MAX_STRIDE:
        raise SettingError(
            f"stride must be a whole number from 1 (every frame scored) to {MAX_STRIDE}, got {stride}"
        )
    return stride


@dataclass(frozen=True)
class Scoring:
    """How runs are scored, by every job that scores them: a detector, calibration, an evaluation."""

    k: int = DEFAULT_K  # neighbours retrieved per query
    modality: str = (
        DEFAULT_MODALITY  # what it judges by: `both` (cameras and signals), `cameras` or `signals`
    )

    def __post_init__(self) -> None:  # a bad setting fails before the memory is read
        check_k(self.k)
        check_modality(self.modality)


DEFAULT_SCORING: Final[Scoring] = Scoring()


@dataclass(frozen=True)
class DetectorConfig:
    """What opens a detector on a memory folder (`robofailring.detection.loader.detector_from`): the memory, the
    rule and thresholds that decide, how runs are scored and where the encoder runs; a threshold not given is
    the memory's calibrated one, else the rule's default."""

    memory: Path | None = None  # memory folder (None: a job that opens none, e.g. triage against other runs)
    encoder: str | None = None  # encoder spec; None: the one that built the memory
    data_root: Path | None = None  # where the memory's images are now, when its data moved
    rule: str | None = None  # a scoring rule's name; None: each task's default (contrast, novelty or paper)
    thresholds: Mapping[str, float] = field(default_factory=dict)  # by rule name (`paper`: δ, …)
    scoring: Scoring = DEFAULT_SCORING  # K and the modality judged by
    placement: EncoderPlacement = DEFAULT_PLACEMENT  # device, runtime, cache and Ray cluster of its encoder

    def __post_init__(self) -> None:  # a bad setting fails before the memory is read
        if self.rule is not None:
            rule_named(self.rule)
        for name, value in self.thresholds.items():
            rule_named(name).check_threshold(value)

    @property
    def memory_dir(self) -> Path:
        """The memory folder; SettingError when none was given."""
        if self.memory is None:
            raise SettingError("no memory folder was given to open a detector on (--memory)")
        return Path(self.memory)

    def with_memory(self, memory: Path, **changes: Any) -> DetectorConfig:
        """The same settings on another memory folder (and any other `changes`)."""
        return replace(self, memory=memory, **changes)


DEFAULT_DETECTOR: Final[DetectorConfig] = DetectorConfig()  # every setting at its default, no memory yet
