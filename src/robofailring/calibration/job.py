"""Calibration with a guarantee (docs/rules.md, "Calibration with a guarantee"): δ, γ and η from success runs.

Each success run is replayed with its own episode hidden from both memories (leave-one-out), so
its frames never match themselves in the success memory; its peak score over frames and views is
one conformal score. The threshold of each rule is the split-conformal one of
`robofailring.calibration.conformal.conformal_threshold`, pooled over tasks. With a band
(`robofailring.calibration.bands`: `shift`, `norm`), each run's per-frame score is first corrected by
the band of the other runs, and its peak is the conformal score; the band of all runs is stored.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robofailring.calibration.bands import MIN_BAND_RUNS, POOLED, TASK
from robofailring.calibration.conformal import (
    FprSpread,
    attainable_target_fpr,
    conformal_threshold,
    empirical_fpr,
    fpr_spread,
)
from robofailring.calibration.fusions import DEFAULT_FUSION, fused_raw, fusion_named, per_task_peaks
from robofailring.calibration.policy import DEFAULT_POLICY, ThresholdPolicy
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.detection.band import NONE, Band
from robofailring.detection.config import (
    DEFAULT_SCORING,
    DEFAULT_STRIDE,
    DetectorConfig,
    Scoring,
    check_stride,
)
from robofailring.detection.detector import FailureDetector
from robofailring.detection.loader import detector_from
from robofailring.detection.rules import (
    CONTRAST,
    NOVELTY,
    PAPER,
    PAPER_DELTA,
    ScoringRule,
    rule_named,
    rules_for,
)
from robofailring.encoders.placement import DEFAULT_PLACEMENT, EncoderPlacement
from robofailring.errors import DataError
from robofailring.memory.stored_calibration import StoredCalibration, StoredRule
from robofailring.progress import progress_bar


@dataclass(frozen=True)
class RuleCalibration:
    """One rule's conformal threshold and what it achieved on the runs it was set from."""

    rule: ScoringRule
    threshold: float
    target_fpr: float
    achieved_fpr: float  # share of the calibration runs that reach the threshold (≤ α by construction)
    successes: int
    band: Band | None = None  # the time-indexed band the threshold applies to (None: one number)

    @property
    def spread(self) -> FprSpread:
        """How far the test FPR of this threshold can stray from α with these `successes` runs."""
        return fpr_spread(self.successes, self.target_fpr)


def available_rules(detector: FailureDetector) -> list[ScoringRule]:
    """The rules this detector's memory supports: contrast and novelty need success runs, paper and
    contrast failure runs."""
    return rules_for(successes=detector.memory.successes is not None, failures=len(detector.memory) > 0)


def success_scores(
    detector: FailureDetector,
    successes: Sequence[Trajectory],
    rules: Sequence[ScoringRule],
    *,
    stride: int = DEFAULT_STRIDE,
) -> dict[ScoringRule, list[np.ndarray]]:
    """Per rule, each success run's per-frame score (max over views, uncorrected; NaN where unscored),
    its episode left out of both memories (every `stride`-th frame scored)."""
    by_view = success_view_scores(detector, successes, rules, stride=stride)
    return {rule: [fused_raw(run) for run in runs] for rule, runs in by_view.items()}


def success_view_scores(
    detector: FailureDetector,
    successes: Sequence[Trajectory],
    rules: Sequence[ScoringRule],
    *,
    progress: Callable[[int], None] | None = None,
    stride: int = DEFAULT_STRIDE,
    too_short: list[str] | None = None,
    short_views: list[Skipped] | None = None,
    tasks: list[str] | None = None,
) -> dict[ScoringRule, list[dict[str, np.ndarray]]]:
    """Per rule, each success run's per-frame score per view (uncorrected; NaN where unscored), its
    episode left out of both memories.

    `stride` scores every N-th frame, as the runs the threshold will judge are scored; the keys of
    runs with no view of 2+ frames (nothing to score) are appended to `too_short`, the views of fewer
    than 2 frames of the runs scored to `short_views`, and the task of each run scored to `tasks`."""
    scores: dict[ScoringRule, list[dict[str, np.ndarray]]] = {rule: [] for rule in rules}
    for trajectory in successes:
        try:
            trace = detector.run(trajectory, leave_one_out=True, stride=stride, keep_queries=False)
        except DataError:
            if too_short is not None:
                too_short.append(trajectory.key)
        else:
            for rule in rules:
                scores[rule].append(trace.scores_of(rule))
            if tasks is not None:
                tasks.append(trajectory.task)
            if short_views is not None:
                short_views += trace.short_views
        if progress is not None:
            progress(1)
    return scores


def calibrate_rules(
    detector: FailureDetector,
    successes: Sequence[Trajectory],
    policy: ThresholdPolicy,
    *,
    rules: Sequence[ScoringRule] | None = None,
    progress: Callable[[int], None] | None = None,
    stride: int = DEFAULT_STRIDE,
    too_short: list[str] | None = None,
    short_views: list[Skipped] | None = None,
    at_best: bool = False,
    scores_out: list[tuple[dict[ScoringRule, list[dict[str, np.ndarray]]], list[str]]] | None = None,
) -> dict[ScoringRule, RuleCalibration]:
    """The conformal threshold of every rule (default: all the memory supports) as `policy` sets it: at level
    `target_fpr`, on its `band` (`none`, `shift`, `norm`) fitted on the same runs, its views fused by its
    `fusion` (`robofailring.calibration.fusions`), one band over all tasks or, with `band_scope` `task`, one per
    task that has enough runs (`robofailring.calibration.bands`); the paper rule keeps one δ, as in the paper
    (§3.3).

    Too few runs for `target_fpr` are a DataError; with `at_best` (an evaluation on small data) a rule
    is calibrated at the smallest level its runs allow instead (its `target_fpr` says which: no
    guarantee at the asked one), and a rule none of whose runs could be scored is left out. `scores_out`
    receives the runs' per-view scores and tasks (an evaluation calibrates each modality alone from them)."""
    chosen = list(rules) if rules is not None else available_rules(detector)
    tasks: list[str] = []
    scores = success_view_scores(
        detector,
        successes,
        chosen,
        progress=progress,
        stride=stride,
        too_short=too_short,
        short_views=short_views,
        tasks=tasks,
    )
    if scores_out is not None:
        scores_out.append((scores, tasks))
    fusion_peaks = fusion_named(policy.fusion).peaks
    calibrations = {}
    for rule, runs in scores.items():
        if not runs:
            raise DataError(f"none of the {len(successes)} success trajectories has a view of 2+ frames")
        kind = policy.band if rule is not PAPER else NONE  # δ stays the paper's
        if policy.band_scope == TASK:
            values, fitted = per_task_peaks(fusion_peaks, runs, tasks, kind)
        else:
            values, fitted = fusion_peaks(runs, kind, tasks)
        scored = [v for v in values if math.isfinite(v)]
        if at_best and not scored:
            continue
        level = attainable_target_fpr(len(scored), policy.target_fpr) if at_best else policy.target_fpr
        try:
            threshold = conformal_threshold(scored, level)
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
            target_fpr=level,
            achieved_fpr=empirical_fpr(scored, threshold),
            successes=len(scored),
            band=fitted,
        )
    return calibrations


@dataclass(frozen=True)
class CalibrateConfig:
    data: DataSelection  # the dataset holding success runs of the memory's tasks, how it is read
    memory: Path  # the memory calibrated: its thresholds are written into its manifest
    encoder: str | None = None  # the spec its encoder is opened by (None: the memory's own)
    scoring: Scoring = DEFAULT_SCORING  # scored as its detector will score: K, modality
    placement: EncoderPlacement = DEFAULT_PLACEMENT  # where its encoder runs: device, runtime, cache, Ray
    threshold_policy: ThresholdPolicy = DEFAULT_POLICY  # the target α, band and fusion
    split: str | None = "train"  # successes of this split (None: all; ignored if the data has no splits)
    stride: int = DEFAULT_STRIDE  # score every stride-th frame of each success run

    def __post_init__(self) -> None:  # bad settings fail before any frame is encoded
        check_stride(self.stride)

    @property
    def detector(self) -> DetectorConfig:
        """The detector that scores the success runs: no rule (calibration sets every rule's), δ the default."""
        given = {PAPER.name: PAPER_DELTA}
        return DetectorConfig(
            self.memory, self.encoder, thresholds=given, scoring=self.scoring, placement=self.placement
        )


@dataclass(frozen=True)
class Calibration:
    """What `calibrate` chose and stored: a threshold per rule the memory supports, by rule name."""

    thresholds: dict[str, float]  # by rule name, in the order calibrated
    achieved_fprs: dict[str, float]  # by rule name: share of the calibration runs reaching the threshold
    target_fpr: float
    successes: int
    encoder: str
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the data not read
    skipped_too_short: list[str] = field(default_factory=list)  # success runs with no view of 2+ frames
    fpr_spread: FprSpread | None = None  # the realised test FPR's range with these `successes` runs
    band: str = NONE  # the thresholds' time-indexed band (none: each threshold is one number)
    band_asked: str = NONE  # the band asked for (none is used with fewer than MIN_BAND_RUNS runs)
    fusion: str = DEFAULT_FUSION  # per-view / per-modality: each view / modality corrected by its own band

    @property
    def delta(self) -> float | None:
        """The paper rule's δ (None: the memory has no failure runs)."""
        return self.thresholds.get(PAPER.name)

    @property
    def gamma(self) -> float | None:
        """The contrast rule's γ (None: the memory lacks success or failure runs)."""
        return self.thresholds.get(CONTRAST.name)

    @property
    def eta(self) -> float | None:
        """The novelty rule's η (None: the memory has no success runs)."""
        return self.thresholds.get(NOVELTY.name)

    def to_text(self, memory: Path) -> str:
        """The summary `robofailring calibrate` prints: each calibrated rule's threshold."""
        head = (
            f"calibrated for encoder {self.encoder} on {self.successes} success runs (target FPR "
            f"{100 * self.target_fpr:g} %); stored in {memory}/manifest.json"
        )
        lines = [head]
        if self.band_asked != NONE and self.band == NONE:
            lines.append(
                f"no time-indexed band: {self.successes} calibration runs are too few to fit one (at least "
                f"{MIN_BAND_RUNS}); each threshold is one number"
            )
        if self.band != NONE:
            lines.append(
                f"time-indexed band {self.band!r}: each threshold applies to the score corrected by the "
                + ("mean" if self.band == "shift" else "mean and spread")
                + " of these runs' scores at the same frame (a line over time on the raw score)"
                + fusion_named(self.fusion).summary_note()
            )
        for name, threshold in self.thresholds.items():
            rule = rule_named(name)
            note = ", own episode left out of the success memory" if rule.needs_successes else ""
            lines.append(
                f"{rule.symbol} = {threshold:.6f} ({rule.name} rule): FPR "
                f"{100 * self.achieved_fprs[name]:.1f} % on those runs{note}"
            )
        if self.fpr_spread is not None:
            lines.append(f"the promise holds on average: {self.fpr_spread.to_text()}")
        text = "\n".join(lines)
        if self.skipped_too_short:
            text += f"\nskipped: {len(self.skipped_too_short)} success run(s) with no view of 2+ frames (nothing to score)"
            text += "".join(f"\n  skipped {key}" for key in self.skipped_too_short[:10])
        return text


def calibrate(config: CalibrateConfig, *, progress: Callable[[int], None] | None = None) -> Calibration:
    """Set every rule's threshold the memory supports (split conformal, level = target FPR) on success runs
    and store each under its rule's name in the manifest."""
    policy, memory_dir = config.threshold_policy, config.memory
    detector = detector_from(config.detector)
    memory = detector.memory
    dataset = config.data.load(vocabulary=memory.vocabulary)
    source, skipped_inputs = dataset.judged("calibrate")  # an unlabelled run is never taken for a success
    has_splits = any(t.split for t in source)
    successes = [
        t
        for t in source
        if not t.is_failure and t.task in memory.tasks and (not has_splits or config.split in (None, t.split))
    ]
    if not successes:
        raise DataError(
            f"no success trajectories of the memory's tasks in {config.data.root} (split {config.split!r})"
        )
    too_short: list[str] = []
    short_views: list[Skipped] = []  # listed with what was not read: status 3, as in every verb
    with progress_bar(total=len(successes), desc="calibrating", unit="traj") as bar:

        def advance(count: int) -> None:
            bar.update(count)
            if progress is not None:
                progress(count)

        found = calibrate_rules(
            detector,
            successes,
            policy,
            progress=advance,
            stride=config.stride,
            too_short=too_short,
            short_views=short_views,
        )
    widest = max(found.values(), key=lambda calibration: calibration.successes)
    spread = widest.spread  # computed once: it searches for the runs a tighter bound needs
    calibrated = memory.with_calibration(
        StoredCalibration(
            encoder=memory.encoder,
            rules={rule.name: _stored_rule(calibration) for rule, calibration in found.items()},
            method="split conformal, own episode left out"
            + fusion_named(policy.fusion).method_note()
            + (", a band per task with enough runs" if policy.band_scope != POOLED else ""),
            target_fpr=policy.target_fpr,
            successes=widest.successes,
            data=str(config.data.root.resolve()),
            split=config.split,
            k=detector.k,
            stride=config.stride,
            modality=detector.modality,
        )
    )
    calibrated.write_manifest(memory_dir)
    return Calibration(
        thresholds={rule.name: calibration.threshold for rule, calibration in found.items()},
        achieved_fprs={rule.name: calibration.achieved_fpr for rule, calibration in found.items()},
        target_fpr=policy.target_fpr,
        successes=widest.successes,
        encoder=memory.encoder,
        skipped_inputs=[*skipped_inputs, *short_views],
        skipped_too_short=too_short,
        fpr_spread=spread,
        band=next((c.band.kind for c in found.values() if c.band is not None), NONE),
        band_asked=policy.band,
        fusion=policy.fusion,
    )


def _stored_rule(calibration: RuleCalibration) -> StoredRule:
    """One rule's calibration as the manifest keeps it, under the rule's name."""
    return StoredRule(
        threshold=calibration.threshold,
        achieved_fpr=calibration.achieved_fpr,
        band=calibration.band.to_dict() if calibration.band is not None else None,
        fpr_spread=calibration.spread.to_dict(),
        runs=calibration.successes,
    )
