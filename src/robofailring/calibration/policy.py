"""`ThresholdPolicy`: how a job sets thresholds (target α, band, fusion, band scope) as one value, checked
where it is made.

Calibration (`robofailring calibrate`), the evaluation, the encoder comparison and the demo each take
one (docs/rules.md, "Calibration with a guarantee").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from robofailring.calibration.bands import DEFAULT_BAND, DEFAULT_BAND_SCOPE, check_band, check_band_scope
from robofailring.calibration.conformal import check_target_fpr
from robofailring.calibration.fusions import DEFAULT_FUSION, check_fusion

DEFAULT_TARGET_FPR: Final[float] = 0.05


@dataclass(frozen=True)
class ThresholdPolicy:
    """Every rule's threshold set split-conformally on success runs at level `target_fpr`."""

    target_fpr: float = DEFAULT_TARGET_FPR  # α: the false-positive rate allowed
    band: str = DEFAULT_BAND  # γ and η on a time-indexed band: none, shift (μ_t) or norm (μ_t, σ_t)
    # the views: max (one band for all), per-view (each its own band) or per-modality (the cameras', the signals')
    fusion: str = DEFAULT_FUSION
    band_scope: str = (
        DEFAULT_BAND_SCOPE  # pooled: one band over all tasks; task: a band per task with enough runs
    )

    def __post_init__(self) -> None:  # a bad setting fails before any frame is encoded
        check_target_fpr(self.target_fpr)
        check_band(self.band)
        check_fusion(self.fusion)
        check_band_scope(self.band_scope)


DEFAULT_POLICY: Final[ThresholdPolicy] = ThresholdPolicy()
