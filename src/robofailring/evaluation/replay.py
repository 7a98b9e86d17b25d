"""An evaluation's replay: every test run scored once by the detector (its trace kept, for recordings to reuse),
and every rule judged on those traces at its threshold, per modality too where the runs have signals."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from robofailring.data.grounding import Vocabulary
from robofailring.data.model import Skipped, Trajectory
from robofailring.detection.detector import DetectionTrace, FailureDetector, Place
from robofailring.detection.rules import PAPER
from robofailring.detection.scored import prefetch_scored
from robofailring.encoders import CachedEncoder
from robofailring.errors import DataError, SplitError
from robofailring.evaluation.metrics import ScoredTrajectory
from robofailring.evaluation.modalities import ModalityResult, modality_results
from robofailring.evaluation.per_rule import RuleResult, evaluate_rule, scored_by_rule
from robofailring.evaluation.thresholds import Thresholds
from robofailring.progress import progress_bar

PlaceFor = Callable[[str], Place]  # task -> the `place` hook of its runs (e.g. their points in a memory map)


def prefetch_runs(
    encoder: CachedEncoder,
    test: Sequence[Trajectory],
    train: Sequence[Trajectory],
    *,
    known: set[str],
    stride: int,
) -> None:
    """Hand the encoder every frame the replay and the calibration will score (the test runs, the
    training successes), so an encoder working ahead (Ray) encodes them in one pass."""
    runs = [*test, *(t for t in train if not t.is_failure)]
    prefetch_scored(encoder, (t for t in runs if t.task in known), stride=stride)


@dataclass(frozen=True)
class Replayed:
    """The test runs scored, their traces by run key, and the runs left out."""

    scored: list[ScoredTrajectory]
    traces: dict[str, DetectionTrace]
    unknown_task: list[str]  # keys of the runs whose task the memory has not
    too_short: list[str]  # keys of the runs with no view of 2+ frames
    first: Trajectory  # the first run scored: the one the latency is measured on

    @property
    def views(self) -> list[str]:
        return sorted({v for s in self.scored for v in s.similarity})


def replay(
    detector: FailureDetector,
    test: Sequence[Trajectory],
    *,
    stride: int,
    place: PlaceFor | None,
    desc: str,
) -> Replayed:
    """Every test run of a task in the detector's memory scored once (every `stride`-th frame; `place(task)`:
    the `place` hook of its runs); SplitError where none is."""
    known = set(detector.memory.tasks)
    scored: list[ScoredTrajectory] = []
    traces: dict[str, DetectionTrace] = {}
    skipped: list[str] = []
    too_short: list[str] = []
    with progress_bar(total=len(test), desc=desc, unit="traj") as bar:
        for trajectory in test:
            bar.update(1)
            if trajectory.task not in known:
                skipped.append(trajectory.key)
                continue
            try:
                trace = detector.run(
                    trajectory,
                    stride=stride,
                    keep_queries=False,
                    place=place(trajectory.task) if place is not None else None,
                )
            except DataError:
                too_short.append(trajectory.key)
                continue
            traces[trajectory.key] = trace
            scored.append(ScoredTrajectory.of(trajectory, trace.length, trace.similarity))
    if not scored:
        raise SplitError(
            f"none of the {len(test)} test trajectories has a task in the memory ({sorted(known)})"
        )
    first = next(t for t in test if t.key in traces)
    return Replayed(scored, traces, skipped, too_short, first)


@dataclass(frozen=True)
class Judged:
    """Every rule's result on the replayed runs, and their traces as the paper's tables read them."""

    traces: dict[str, DetectionTrace]  # the paper rule at δ, the other rules' thresholds beside it
    rules: dict[str, RuleResult]
    modalities: dict[str, dict[str, ModalityResult]]  # per rule: cameras, signals, both (calibrated here)

    @property
    def skipped_inputs(self) -> list[Skipped]:
        """What the runs' traces did not read: their skipped inputs and views too short to score."""
        return [s for trace in self.traces.values() for s in [*trace.skipped_inputs, *trace.short_views]]


def judge(replayed: Replayed, thresholds: Thresholds, vocabulary: Vocabulary | None) -> Judged:
    """Each rule of `thresholds` judged on the replayed runs at its threshold, and, where the thresholds were
    calibrated here, each modality alone at its own."""
    evaluated = {rule.name: threshold for rule, threshold in thresholds.values.items()}
    traces = {
        key: DetectionTrace(
            **{**trace.__dict__, "rule": PAPER, "thresholds": {**trace.thresholds, **evaluated}}
        )
        for key, trace in replayed.traces.items()
    }
    labels = {t.key: t for t in replayed.scored}
    found = thresholds.found
    rules = {
        rule.name: evaluate_rule(
            scored_by_rule(traces, labels, rule),
            rule,
            threshold,
            calibrated=thresholds.calibrated[rule],
            spread=found[rule].spread if found is not None else None,
            level=found[rule].target_fpr if found is not None else None,
        )
        for rule, threshold in thresholds.values.items()
    }
    modalities = (
        modality_results(traces, labels, thresholds.scores, rules, vocabulary)
        if thresholds.scores is not None
        else {}
    )
    return Judged(traces, rules, modalities)
