"""Calibration with a guarantee (README, "Calibration with a guarantee"): δ, γ and η from success runs.

Each success run is replayed with its own episode hidden from both memories (leave-one-out), so
its frames never match themselves in the success memory; its peak score over frames and views is
one conformal score. The threshold of each rule is the split-conformal one of
`robofailring.detection.conformal.conformal_threshold`, pooled over tasks.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from robofailring.data.layouts import load_dataset
from robofailring.data.model import Skipped, Trajectory
from robofailring.detection.conformal import (
    FprSpread,
    check_target_fpr,
    conformal_threshold,
    empirical_fpr,
    fpr_spread,
)
from robofailring.detection.detector import FailureDetector, check_k, check_stride
from robofailring.detection.loader import open_detector
from robofailring.detection.rules import CONTRAST, NOVELTY, PAPER, PAPER_DELTA, ScoringRule, rules_for
from robofailring.errors import DataError
from robofailring.memory.manifest import StoredCalibration
from robofailring.progress import progress_bar


@dataclass(frozen=True)
class RuleCalibration:
    """One rule's conformal threshold and what it achieved on the runs it was set from."""

    rule: ScoringRule
    threshold: float
    target_fpr: float
    achieved_fpr: float  # share of the calibration runs that reach the threshold (≤ α by construction)
    successes: int

    @property
    def spread(self) -> FprSpread:
        """How far the test FPR of this threshold can stray from α with these `successes` runs."""
        return fpr_spread(self.successes, self.target_fpr)


def available_rules(detector: FailureDetector) -> list[ScoringRule]:
    """The rules this detector's memory supports: contrast and novelty need success runs, paper and
    contrast failure runs."""
    return rules_for(successes=detector.memory.successes is not None, failures=len(detector.memory) > 0)


def success_peaks(
    detector: FailureDetector,
    successes: Sequence[Trajectory],
    rules: Sequence[ScoringRule],
    *,
    progress: Callable[[int], None] | None = None,
    stride: int = 1,
    too_short: list[str] | None = None,
) -> dict[ScoringRule, list[float]]:
    """Per rule, each success run's peak score, its episode left out of both memories.

    `stride` scores every N-th frame, as the runs the threshold will judge are scored; the keys of
    runs with no view of 2+ frames (nothing to score) are appended to `too_short`."""
    peaks: dict[ScoringRule, list[float]] = {rule: [] for rule in rules}
    for trajectory in successes:
        try:
            trace = detector.run(trajectory, leave_one_out=True, stride=stride, keep_queries=False)
        except DataError:
            if too_short is not None:
                too_short.append(trajectory.key)
        else:
            for rule in rules:
                peaks[rule].append(float(trace.with_rule(rule, 0.0).max_score().max()))
        if progress is not None:
            progress(1)
    return peaks


def calibrate_rules(
    detector: FailureDetector,
    successes: Sequence[Trajectory],
    target_fpr: float,
    *,
    rules: Sequence[ScoringRule] | None = None,
    progress: Callable[[int], None] | None = None,
    stride: int = 1,
    too_short: list[str] | None = None,
) -> dict[ScoringRule, RuleCalibration]:
    """The conformal threshold of every rule (default: all the memory supports) at level `target_fpr`."""
    chosen = list(rules) if rules is not None else available_rules(detector)
    peaks = success_peaks(detector, successes, chosen, progress=progress, stride=stride, too_short=too_short)
    calibrations = {}
    for rule, values in peaks.items():
        if not values:
            raise DataError(f"none of the {len(successes)} success trajectories has a view of 2+ frames")
        scored = [v for v in values if math.isfinite(v)]
        try:
            threshold = conformal_threshold(scored, target_fpr)
        except DataError as error:
            if len(scored) < len(values):
                raise DataError(
                    f"{error} ({len(values) - len(scored)} of the {len(values)} runs are the only success run of "
                    f"their task, so leaving their episode out leaves nothing to contrast them with)"
                ) from error
            raise
        calibrations[rule] = RuleCalibration(
            rule=rule,
            threshold=threshold,
            target_fpr=target_fpr,
            achieved_fpr=empirical_fpr(scored, threshold),
            successes=len(scored),
        )
    return calibrations


@dataclass(frozen=True)
class CalibrateConfig:
    data: Path  # dataset holding success trajectories to calibrate on
    memory: Path  # memory directory; the chosen δ is written into its manifest
    target_fpr: float = 0.05
    split: str | None = "train"  # successes of this split (None: all; ignored if the data has no splits)
    k: int = 5
    cache_dir: Path | None = None
    device: str | None = None
    stride: int = 1  # score every stride-th frame of each success run
    labels: Path | None = None  # labels file for data whose names do not say the outcome (LeRobot)
    task: str | None = None  # task of episodes whose names do not say it
    views: str | None = None  # `--views`: `a,b` picks views, `src=name` renames (default: all)

    def __post_init__(self) -> None:  # bad settings fail before any frame is encoded
        check_k(self.k)
        check_stride(self.stride)
        check_target_fpr(self.target_fpr)


@dataclass(frozen=True)
class Calibration:
    delta: float | None  # None: the memory has no failure runs (success runs only)
    target_fpr: float
    achieved_fpr: float | None  # δ's
    successes: int
    encoder: str
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the data not read
    gamma: float | None = None  # the contrast rule's γ, when the memory has success and failure runs
    gamma_achieved_fpr: float | None = None
    skipped_too_short: list[str] = field(default_factory=list)  # success runs with no view of 2+ frames
    eta: float | None = None  # the novelty rule's η, when the memory has success runs
    eta_achieved_fpr: float | None = None
    fpr_spread: FprSpread | None = None  # the realised test FPR's range with these `successes` runs

    def to_text(self, memory: Path) -> str:
        """The summary `robofailring calibrate` prints: δ, γ and η, those the memory supports."""
        head = (
            f"calibrated for encoder {self.encoder} on {self.successes} success runs (target FPR "
            f"{100 * self.target_fpr:.1f} %); stored in {memory}/manifest.json"
        )
        lines = [head]
        for rule, threshold, achieved, note in (
            (PAPER, self.delta, self.achieved_fpr, ""),
            (CONTRAST, self.gamma, self.gamma_achieved_fpr, ", own episode left out of the success memory"),
            (NOVELTY, self.eta, self.eta_achieved_fpr, ", own episode left out of the success memory"),
        ):
            if threshold is not None and achieved is not None:
                lines.append(
                    f"{rule.symbol} = {threshold:.6f} ({rule.name} rule): FPR {100 * achieved:.1f} % on those runs{note}"
                )
        if self.fpr_spread is not None:
            lines.append(f"the promise holds on average: {self.fpr_spread.to_text()}")
        text = "\n".join(lines)
        if self.skipped_too_short:
            text += f"\nskipped: {len(self.skipped_too_short)} success run(s) with no view of 2+ frames (nothing to score)"
            text += "".join(f"\n  skipped {key}" for key in self.skipped_too_short[:10])
        return text


def calibrate(config: CalibrateConfig, *, progress: Callable[[int], None] | None = None) -> Calibration:
    """Set δ and γ (split conformal, level = target FPR) on success runs and store them in the manifest."""
    detector = open_detector(
        config.memory,
        device=config.device,
        cache_dir=config.cache_dir,
        k=config.k,
        delta=PAPER_DELTA,
    )
    memory = detector.memory
    dataset = load_dataset(
        config.data, task=config.task, labels=config.labels, views=config.views, vocabulary=memory.vocabulary
    )
    dataset.require_labels("calibrate")
    source = list(dataset.trajectories())
    has_splits = any(t.split for t in source)
    successes = [
        t
        for t in source
        if not t.is_failure and t.task in memory.tasks and (not has_splits or config.split in (None, t.split))
    ]
    if not successes:
        raise DataError(
            f"no success trajectories of the memory's tasks in {config.data} (split {config.split!r})"
        )
    too_short: list[str] = []
    with progress_bar(total=len(successes), desc="calibrating", unit="traj") as bar:

        def advance(count: int) -> None:
            bar.update(count)
            if progress is not None:
                progress(count)

        found = calibrate_rules(
            detector,
            successes,
            config.target_fpr,
            progress=advance,
            stride=config.stride,
            too_short=too_short,
        )
    paper, contrast, novelty = found.get(PAPER), found.get(CONTRAST), found.get(NOVELTY)
    widest = max(found.values(), key=lambda calibration: calibration.successes)
    spread = widest.spread  # computed once: it searches for the runs a tighter bound needs
    calibrated = memory.with_calibration(
        StoredCalibration(
            encoder=memory.encoder,
            delta=paper.threshold if paper is not None else None,
            gamma=contrast.threshold if contrast is not None else None,
            eta=novelty.threshold if novelty is not None else None,
            method="split conformal, own episode left out",
            target_fpr=config.target_fpr,
            achieved_fpr=paper.achieved_fpr if paper is not None else None,
            gamma_achieved_fpr=contrast.achieved_fpr if contrast is not None else None,
            eta_achieved_fpr=novelty.achieved_fpr if novelty is not None else None,
            successes=widest.successes,
            fpr_spread=spread.to_dict(),
            data=str(Path(config.data).resolve()),
            split=config.split,
            k=config.k,
            stride=config.stride,
        )
    )
    calibrated.write_manifest(config.memory)
    stored = calibrated.manifest.calibration
    assert stored is not None
    return Calibration(
        delta=stored.delta,
        target_fpr=config.target_fpr,
        achieved_fpr=stored.achieved_fpr,
        successes=stored.successes or 0,
        encoder=memory.encoder,
        skipped_inputs=dataset.skipped,
        gamma=stored.gamma,
        gamma_achieved_fpr=stored.gamma_achieved_fpr,
        skipped_too_short=too_short,
        eta=stored.eta,
        eta_achieved_fpr=stored.eta_achieved_fpr,
        fpr_spread=spread,
    )
