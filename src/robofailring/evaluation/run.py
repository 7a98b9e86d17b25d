"""The paper's evaluation (§4): memory from training failures, Recall/FPR sweep, T_s, ablations, review."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from robofailring.atomic import write_text_atomic
from robofailring.calibration.job import RuleCalibration, available_rules, calibrate_rules
from robofailring.data.model import Skipped, Trajectory
from robofailring.detection.detector import DetectionTrace, FailureDetector, Place
from robofailring.detection.loader import detector_with
from robofailring.detection.rules import PAPER, ScoringRule
from robofailring.detection.scored import prefetch_scored
from robofailring.detection.stored import stored_threshold
from robofailring.encoders import CachedEncoder
from robofailring.errors import DataError, SettingError, SplitError
from robofailring.evaluation.folds import cross_validate
from robofailring.evaluation.growth import GrowthPoint, judged
from robofailring.evaluation.job import (
    EvaluateConfig,
    build_training_memory,
    check_disjoint,
    evaluation_encoder,
    select_splits,
)
from robofailring.evaluation.latency import measure_latency
from robofailring.evaluation.metrics import ScoredTrajectory
from robofailring.evaluation.modalities import CalibrationScores, modality_results
from robofailring.evaluation.per_rule import evaluate_rule, scored_by_rule
from robofailring.evaluation.result import EvaluationResult
from robofailring.memory.failure import FailureMemory
from robofailring.memory.success import SuccessMemory
from robofailring.progress import progress_bar

PlaceFor = Callable[[str], Place]  # task -> the `place` hook of its runs (e.g. their points in a memory map)


def run_evaluation(
    config: EvaluateConfig, *, detector: FailureDetector | None = None, place: PlaceFor | None = None
) -> EvaluationResult:
    """Build (or load) the memory, replay every test trajectory once, and measure everything.

    `detector`: a detector on a memory built and loaded already (its memory and encoder are used, not
    `config`'s; its thresholds are the evaluation's own), so a job that holds one does not load it again.
    The result keeps every test trajectory's trace (`EvaluationResult.traces`), for recordings to reuse;
    `place(task)` is the `place` hook its runs are scored with (`FailureDetector.run`), so a recording of
    one needs no second scoring to draw its queries on a map."""
    splits = select_splits(config)
    train, test = splits.train, splits.test
    built: list[Skipped] = []  # what building the training memory did not use (blank frames, signals)
    if detector is None:
        if config.memory is None:  # the memory built here: checked before it is built
            _deployed(
                test,
                config.deployment_successes,
                tasks={t.task for t in train},
                successes=config.success_memory,
            )
        encoder = evaluation_encoder(config)
        if config.memory is not None:
            memory_dir = config.memory
        else:
            memory_dir, built = build_training_memory(config, splits, encoder)
        tested = [selection.root for selection in (config.data, config.test_data) if selection is not None]
        detector = detector_with(config.detector, FailureMemory.load(memory_dir, trusted=tested), encoder)
    else:
        read_from = detector.memory.read_from
        memory_dir = read_from[0] if read_from is not None else config.detector.memory_dir
    memory, encoder = detector.memory, detector.encoder
    check_disjoint(memory, test)
    _prefetch(
        encoder,
        test,
        train if config.threshold_policy is not None else [],
        known=set(memory.tasks),
        stride=config.stride,
    )
    deployed, test, not_deployed = _deploy_successes(
        memory, test, config.deployment_successes, encoder, config.recipe.success_step
    )
    if deployed is not memory:
        memory, detector = deployed, detector_with(config.detector, deployed, encoder)
    calibration_scores: list[CalibrationScores] = []
    thresholds, calibrated, found = _thresholds(config, detector, train, calibration_scores)
    if found is not None:  # calibrated here: the test runs are judged on the bands fitted with the thresholds
        bands = {r.name: c.band for r, c in found.items() if c.band is not None}
        detector = detector_with(config.detector, memory, encoder, bands=bands)
    operating = thresholds.get(PAPER, PAPER.default_threshold)  # no failure runs: the paper tables are empty
    known = set(memory.tasks)
    scored: list[ScoredTrajectory] = []
    traces: dict[str, DetectionTrace] = {}
    skipped: list[str] = []
    too_short: list[str] = []
    with progress_bar(total=len(test), desc=f"replaying {config.name}", unit="traj") as bar:
        for trajectory in test:
            bar.update(1)
            if trajectory.task not in known:
                skipped.append(trajectory.key)
                continue
            try:
                trace = detector.run(
                    trajectory,
                    stride=config.stride,
                    keep_queries=False,
                    place=place(trajectory.task) if place is not None else None,
                )
            except DataError:
                too_short.append(trajectory.key)
                continue
            traces[trajectory.key] = trace
            scored.append(
                ScoredTrajectory(
                    key=trajectory.key,
                    task=trajectory.task,
                    symbol=trajectory.symbol,
                    is_failure=trajectory.is_failure,
                    length=trace.length,
                    similarity=trace.similarity,
                    onset_frame=trajectory.onset_frame,
                    fps=trajectory.frame_rate,
                )
            )
    if not scored:
        raise SplitError(
            f"none of the {len(test)} test trajectories has a task in the memory ({sorted(known)})"
        )
    views = sorted({v for s in scored for v in s.similarity})
    first = next(t for t in test if t.key in traces)
    evaluated = {rule.name: threshold for rule, threshold in thresholds.items()}
    traces = {  # the paper rule at δ, the other rules' thresholds beside it: the paper tables read these
        key: DetectionTrace(
            **{**trace.__dict__, "rule": PAPER, "thresholds": {**trace.thresholds, **evaluated}}
        )
        for key, trace in traces.items()
    }
    labels = {t.key: t for t in scored}
    rules = {
        rule.name: evaluate_rule(
            scored_by_rule(traces, labels, rule),
            rule,
            threshold,
            calibrated=calibrated[rule],
            spread=found[rule].spread if found is not None else None,
            level=found[rule].target_fpr if found is not None else None,
        )
        for rule, threshold in thresholds.items()
    }
    modalities = (
        modality_results(traces, labels, calibration_scores[0], rules, memory.vocabulary)
        if calibration_scores
        else {}
    )
    return EvaluationResult(
        name=config.name,
        encoder=memory.encoder,
        memory=str(memory_dir),
        k=detector.k,
        operating_delta=operating,
        calibrated=calibrated.get(PAPER, False),
        rules=rules,
        modalities=modalities,
        target_fpr=config.threshold_policy.target_fpr
        if config.threshold_policy is not None
        else _stored_target(memory),
        deployment_successes=config.deployment_successes,
        band=next((band.kind for band in detector.bands.values()), "none"),
        views=views,
        scored=scored,
        traces=traces,
        skipped_unknown_task=skipped,
        latency_ms=measure_latency(detector, first),
        skipped_too_short=too_short,
        skipped_inputs=list(
            dict.fromkeys(  # each listed once: a run's own skips (its trace's) are among the dataset's too
                [
                    *splits.skipped,
                    *built,
                    *not_deployed,
                    *(s for trace in traces.values() for s in [*trace.skipped_inputs, *trace.short_views]),
                ]
            )
        ),
        stride=config.stride,
        vocabulary=memory.vocabulary,
        failure_frames=memory.manifest.failure_mode,
        pairing=memory.pairing,
        uncalibrated=[r.name for r in available_rules(detector) if found is not None and r not in found],
        cross_validation=(
            cross_validate(config, list(splits.dataset.trajectories()), encoder)
            if config.folds is not None
            else None
        ),
    )


def check_growth(config: EvaluateConfig) -> None:
    """A curve builds a memory per level from the training data: SettingError for a given memory."""
    if config.memory is not None:
        raise SettingError("--growth builds a memory per level from the training data: leave out --memory")


def growth_curve(
    config: EvaluateConfig, levels: Sequence[int], *, full: EvaluationResult
) -> list[GrowthPoint]:
    """Each level's evaluation of `config` (an `EvaluateConfig` building its memory: `memory` None) with
    `failures_per_task` set, written to `<out>/growth-<n>/` (its memory and `growth-<n>.json`/`.md`),
    then `full` (the evaluation with every failure)."""
    check_growth(config)
    points = []
    for level in levels:
        folder = Path(config.out) / f"growth-{level}"
        result = run_evaluation(
            replace(
                config,
                failures_per_task=level,
                out=folder,
                memory_out=folder / "memory",
                name=f"growth-{level}",
                folds=None,  # the cross-validation is the full evaluation's
            )
        )
        write_evaluation(result, folder)
        points.append(GrowthPoint(level, judged(result.rules, failures=level > 0)))
    points.append(GrowthPoint(None, judged(full.rules, failures=True)))
    return points


def _prefetch(
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


def _stored_target(memory: FailureMemory) -> float | None:
    """The α the memory's stored thresholds were calibrated to, if they belong to its encoder."""
    calibration = memory.manifest.calibration
    return calibration.target_for(memory.encoder) if calibration is not None else None


def _deployed(
    test: Sequence[Trajectory], per_task: int, *, tasks: set[str], successes: bool
) -> list[Trajectory]:
    """The `per_task` test success runs per task of `tasks` that `--deployment-successes` moves; SettingError
    where there is no success memory for them to join, or a task would keep no test success run to measure
    its false positive rate on (its FPR would read "—")."""
    if per_task and not successes:
        raise SettingError(
            f"--deployment-successes {per_task}: the memory has no success memory for them to join (built with "
            "--no-successes); build it with its success runs, or leave out --deployment-successes"
        )
    chosen: list[Trajectory] = []
    for task in sorted({t.task for t in test} & tasks) if per_task else ():
        runs = sorted((t for t in test if t.task == task and not t.is_failure), key=lambda t: t.key)
        if runs and per_task >= len(runs):
            raise SettingError(
                f"--deployment-successes {per_task} would leave task {task!r} no test success run to measure its "
                f"false positive rate on (its test data has {len(runs)}): give at most {len(runs) - 1}"
            )
        chosen += runs[:per_task]
    return chosen


def _deploy_successes(
    memory: FailureMemory, test: list[Trajectory], per_task: int, encoder: CachedEncoder, step: float
) -> tuple[FailureMemory, list[Trajectory], list[Skipped]]:
    """Move `per_task` success runs per task from the test set into the success memory and, where the memory
    has one, the signal memory (in memory only); SettingError before anything is encoded (`_deployed`). The
    runs whose signals did not join (listed as skipped, as a build lists them) come third."""
    if per_task == 0:
        return memory, test, []
    successes = memory.successes
    chosen = _deployed(test, per_task, tasks=set(memory.tasks), successes=successes is not None)
    if successes is None or not chosen:  # (`_deployed` refuses a memory without successes)
        return memory, test, []
    deployed = memory.with_successes(
        successes.extended(SuccessMemory.build(chosen, encoder, step=step, pairing=memory.pairing))
    )
    unused: list[Skipped] = []
    if memory.signals is not None:  # the robot's signals of those runs join its signal memory too
        signals, unused = memory.signals.extended(chosen)
        deployed = deployed.with_signals(signals)
    keys = {t.key for t in chosen}
    return deployed, [t for t in test if t.key not in keys], unused


def _thresholds(
    config: EvaluateConfig,
    detector: FailureDetector,
    train: Sequence[Trajectory],
    scores: list[CalibrationScores] | None = None,
) -> tuple[dict[ScoringRule, float], dict[ScoringRule, bool], dict[ScoringRule, RuleCalibration] | None]:
    """Each rule's threshold: conformal on the training successes, or the memory's stored/default one,
    and whether it was calibrated; the calibrations made here (each with its level, spread and band;
    None: the stored thresholds, with the memory's own bands). Too few training successes for α: each
    rule at the smallest α its runs allow, a rule none of whose runs could be scored left out. `scores`
    receives what they were calibrated from, where they were calibrated here."""
    rules, policy = available_rules(detector), config.threshold_policy
    if policy is None:
        stored = {r: stored_threshold(detector.memory, r) for r in rules}
        return {r: detector.threshold_of(r) for r in rules}, {r: stored[r] is not None for r in rules}, None
    known = set(detector.memory.tasks)
    successes = [t for t in train if not t.is_failure and t.task in known]
    if not successes:
        raise SplitError(
            f"no success trajectory of the memory's tasks in {config.data.root} (split {config.train_split!r}): "
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
            stride=config.stride,
            at_best=True,
            scores_out=collected,
        )
    if scores is not None and collected:
        runs, tasks = collected[0]
        scores.append(
            CalibrationScores(runs, tasks, policy.target_fpr, policy.band, policy.fusion, policy.band_scope)
        )
    if not found:
        raise SplitError(
            f"none of the {len(successes)} training success runs could be scored with its own episode left out "
            "(their task holds no other run to compare them with): no threshold to evaluate; add runs to the "
            f"training split {config.train_split!r}"
        )
    return {r: c.threshold for r, c in found.items()}, {r: True for r in found}, found


def write_evaluation(result: EvaluationResult, out: Path) -> tuple[Path, Path]:
    """evaluation.json and evaluation.md under `out`, written atomically."""
    out = Path(out)
    json_path, md_path = out / f"{result.name}.json", out / f"{result.name}.md"
    write_text_atomic(json_path, json.dumps(result.to_dict(), indent=2), claim=True)
    write_text_atomic(md_path, result.to_markdown() + "\n", claim=True)
    return json_path, md_path
