"""The thresholds an evaluation judges every rule at: calibrated on the training split's success runs (at α, or
the smallest α their runs allow) by a `ThresholdPolicy`, or the memory's stored ones."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robofailring.calibration.job import RuleCalibration, available_rules, calibrate_rules
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.model import Trajectory
from robofailring.detection.band import Band
from robofailring.detection.detector import FailureDetector
from robofailring.detection.rules import ScoringRule
from robofailring.detection.stored import stored_threshold
from robofailring.errors import SplitError
from robofailring.evaluation.modalities import CalibrationScores
from robofailring.memory.failure import FailureMemory
from robofailring.progress import progress_bar


@dataclass(frozen=True)
class Thresholds:
    """Each rule's threshold, whether it was calibrated, and the calibrations made here."""

    values: dict[ScoringRule, float]
    calibrated: dict[ScoringRule, bool]
    # calibrated here: each rule's with its level, spread and band; None: the stored thresholds, the memory's bands
    found: dict[ScoringRule, RuleCalibration] | None
    scores: CalibrationScores | None = None  # what they were calibrated from, where they were calibrated here

    @property
    def bands(self) -> dict[str, Band]:
        """The bands fitted with the thresholds calibrated here, by rule name."""
        return {r.name: c.band for r, c in (self.found or {}).items() if c.band is not None}


def evaluation_thresholds(
    detector: FailureDetector,
    train: Sequence[Trajectory],
    policy: ThresholdPolicy | None,
    *,
    stride: int,
    data_root: Path,
    train_split: str,
) -> Thresholds:
    """Each rule's threshold: conformal on the training successes (`train`, the `train_split` of `data_root`)
    by `policy`, or the memory's stored/default one (`policy` None). Too few training successes for α: each
    rule at the smallest α its runs allow, a rule none of whose runs could be scored left out."""
    rules = available_rules(detector)
    if policy is None:
        stored = {r: stored_threshold(detector.memory, r) for r in rules}
        return Thresholds(
            {r: detector.threshold_of(r) for r in rules}, {r: stored[r] is not None for r in rules}, None
        )
    known = set(detector.memory.tasks)
    successes = [t for t in train if not t.is_failure and t.task in known]
    if not successes:
        raise SplitError(
            f"no success trajectory of the memory's tasks in {data_root} (split {train_split!r}): "
            "the evaluation calibrates its thresholds on success runs; add success episodes of those tasks "
            "to that split, or name another with --train-split"
        )
    collected: list[tuple[dict[ScoringRule, list[dict[str, np.ndarray]]], list[str]]] = []
    with progress_bar(total=len(successes), desc="calibrating", unit="traj") as bar:
        found = calibrate_rules(
            detector,
            successes,
            policy,
            rules=rules,
            progress=bar.update,
            stride=stride,
            at_best=True,
            scores_out=collected,
        )
    scores = None
    if collected:
        runs, tasks = collected[0]
        scores = CalibrationScores(
            runs, tasks, policy.target_fpr, policy.band, policy.fusion, policy.band_scope
        )
    if not found:
        raise SplitError(
            f"none of the {len(successes)} training success runs could be scored with its own episode left out "
            "(their task holds no other run to compare them with): no threshold to evaluate; add runs to the "
            f"training split {train_split!r}"
        )
    return Thresholds({r: c.threshold for r, c in found.items()}, {r: True for r in found}, found, scores)


def stored_target(memory: FailureMemory) -> float | None:
    """The α the memory's stored thresholds were calibrated to, if they belong to its encoder."""
    calibration = memory.manifest.calibration
    return calibration.target_for(memory.encoder) if calibration is not None else None
