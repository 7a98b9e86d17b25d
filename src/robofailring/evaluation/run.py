"""The paper's evaluation (§4): memory from training failures, Recall/FPR sweep, T_s, ablations, review."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from robofailring.atomic import write_text_atomic
from robofailring.data.layouts import Dataset, load_dataset
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.splits import split_of
from robofailring.data.vocabulary import read_vocabulary
from robofailring.detection.band import DEFAULT_BAND, Band, check_band
from robofailring.detection.conformal import FprSpread, check_target_fpr
from robofailring.detection.detector import (
    DetectionTrace,
    FailureDetector,
    check_k,
    check_stride,
)
from robofailring.detection.rules import PAPER, ScoringRule
from robofailring.detection.stored import stored_threshold
from robofailring.encoders import CachedEncoder, open_encoder
from robofailring.errors import DataError, RoboFailRingError, SettingError
from robofailring.evaluation.growth import GrowthPoint, judged
from robofailring.evaluation.latency import measure_latency
from robofailring.evaluation.metrics import PAPER_DELTAS, ScoredTrajectory
from robofailring.evaluation.per_rule import evaluate_rule, scored_by_rule
from robofailring.evaluation.result import EvaluationResult
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.failure import FailureMemory
from robofailring.memory.references import absolute_reference
from robofailring.memory.success import SuccessMemory
from robofailring.memory.thinning import DEFAULT_STEP
from robofailring.progress import progress_bar


@dataclass(frozen=True)
class EvaluateConfig:
    data: Path  # dataset whose training split's failures form the memory
    out: Path  # folder for evaluation.json and evaluation.md (and memory/ when built here)
    encoder: str = "pixels"  # encoder spec; must match --memory when one is given
    memory: Path | None = None  # an existing memory (its failures must not be in the test set)
    memory_out: Path | None = None  # where a memory built here is saved (default out/memory)
    test_data: Path | None = None  # a second dataset to test on (e.g. out-of-distribution)
    train_split: str = "train"
    test_split: str = "test"
    test_fraction: float = 0.5  # for datasets without splits: a deterministic hash split
    deltas: tuple[float, ...] = PAPER_DELTAS
    k: int = 5
    name: str = "evaluation"
    cache_dir: Path | None = None
    device: str | None = None
    stride: int = 1  # score every stride-th frame of a test trajectory (t_det, T_s in original frames)
    labels: Path | None = None  # labels file for data whose names do not say the outcome (LeRobot)
    vocabulary: Path | None = None  # the data's own failure symbols (JSON/YAML), kept with the memory built
    target_fpr: float | None = 0.05  # calibrate both rules on training successes; None: stored thresholds
    successes: bool = True  # build the success memory beside the failure memory (contrast rule)
    success_step: float = (
        DEFAULT_STEP  # thinning of success runs (robofailring.memory.thinning); 0 keeps every frame
    )
    deployment_successes: int = 0  # per task: test success runs moved into the success memory
    task: str | None = None  # task of episodes whose names do not say it
    views: str | None = None  # `--views`: `a,b` picks views, `src=name` renames (default: all)
    band: str = DEFAULT_BAND  # time-indexed thresholds when calibrating here: none, shift or norm
    failures_per_task: int | None = None  # the memory built here holds N training failures per task
    # (`labelled_failures`; 0: success runs only, judged by the novelty rule); None: all of them

    def __post_init__(self) -> None:  # bad settings fail before any frame is encoded
        check_k(self.k)
        check_stride(self.stride)
        check_band(self.band)
        if self.target_fpr is not None:
            check_target_fpr(self.target_fpr)
        if self.deployment_successes < 0:
            raise SettingError(f"deployment successes must be ≥ 0, got {self.deployment_successes}")
        if self.failures_per_task is not None and self.failures_per_task < 0:
            raise SettingError(f"failures per task must be ≥ 0, got {self.failures_per_task}")
        for delta in self.deltas:
            PAPER.check_threshold(delta)
        if not 0.0 < self.test_fraction < 1.0:
            raise SettingError(f"test fraction must lie in (0, 1), got {self.test_fraction}")


@dataclass(frozen=True)
class Splits:
    """The training and test trajectories of an evaluation, and the dataset the training ones come from."""

    train: list[Trajectory]
    test: list[Trajectory]
    dataset: Dataset  # `config.data`: the training split's dataset
    skipped: list[Skipped]  # what the loaders of the training and test datasets did not read


def select_splits(config: EvaluateConfig) -> Splits:
    """The training and test trajectories, disjoint by construction and checked."""
    vocabulary = read_vocabulary(config.vocabulary) if config.vocabulary is not None else None
    dataset = load_dataset(
        config.data, task=config.task, labels=config.labels, views=config.views, vocabulary=vocabulary
    )
    dataset.require_labels("evaluate")
    source = list(dataset.trajectories())
    skipped = list(dataset.skipped)
    has_splits = any(t.split for t in source)
    train = [
        t
        for t in source
        if split_of(t, has_splits=has_splits, test_fraction=config.test_fraction) == config.train_split
    ]
    if config.test_data is None:
        test = [
            t
            for t in source
            if split_of(t, has_splits=has_splits, test_fraction=config.test_fraction) == config.test_split
        ]
    else:
        other_dataset = load_dataset(
            config.test_data,
            task=config.task,
            labels=config.labels,
            views=config.views,
            vocabulary=vocabulary,
        )
        other_dataset.require_labels("evaluate")
        other = list(other_dataset.trajectories())
        skipped += other_dataset.skipped
        other_has_splits = any(t.split for t in other)
        test = [t for t in other if not other_has_splits or t.split == config.test_split]
    if not test:
        raise DataError(
            f"no test trajectories (split {config.test_split!r}) in {config.test_data or config.data}"
        )
    return Splits(train=train, test=test, dataset=dataset, skipped=skipped)


def check_disjoint(memory: FailureMemory, test: Sequence[Trajectory]) -> None:
    """No trajectory may be both in the memory and in the test set (compared by its image files)."""
    in_memory = {absolute_reference(ref) for entry in memory.entries for ref in (entry.start, entry.end)}
    for trajectory in test:
        for frames in trajectory.views.values():
            if (
                frames
                and {absolute_reference(frames[0].reference), absolute_reference(frames[-1].reference)}
                & in_memory
            ):
                raise RoboFailRingError(
                    f"test trajectory {trajectory.key} ({trajectory.source}) is also in the memory; "
                    "evaluate on a split the memory was not built from"
                )


def build_training_memory(
    config: EvaluateConfig, splits: Splits | None = None, encoder: CachedEncoder | None = None
) -> Path:
    """Build the memory from the training split's failures (and successes) and save it to `config.memory_out`."""
    if encoder is None:
        encoder = open_encoder(config.encoder, device=config.device, cache_dir=config.cache_dir)
    if splits is None:
        splits = select_splits(config)
    provenance = Provenance(
        data=Path(config.data),
        encoder=config.encoder,
        layout=splits.dataset.layout,
        views=splits.dataset.views,
        split=config.train_split,
        skipped_inputs=splits.dataset.skipped,
    )
    memory, _ = build_memories(
        labelled_failures(splits.train, config.failures_per_task),
        encoder,
        provenance=provenance,
        successes=config.successes,
        success_step=config.success_step,
        vocabulary=read_vocabulary(config.vocabulary) if config.vocabulary is not None else None,
    )
    memory_dir = config.memory_out or Path(config.out) / "memory"
    memory.save(memory_dir)
    return memory_dir


def labelled_failures(trajectories: Sequence[Trajectory], per_task: int | None) -> list[Trajectory]:
    """The success runs and `per_task` failure runs of each task (None: all of them), the failures
    in a fixed pseudo-random order (a hash of their key), so the few that are labelled are of mixed types."""
    if per_task is None:
        return list(trajectories)
    kept: dict[str, int] = {}
    chosen = []
    for trajectory in sorted(
        trajectories, key=lambda t: hashlib.blake2b(t.key.encode(), digest_size=8).digest()
    ):
        if trajectory.is_failure:
            if kept.get(trajectory.task, 0) >= per_task:
                continue
            kept[trajectory.task] = kept.get(trajectory.task, 0) + 1
        chosen.append(trajectory)
    return chosen


def run_evaluation(config: EvaluateConfig) -> EvaluationResult:
    """Build (or load) the memory, replay every test trajectory once, and measure everything."""
    encoder = open_encoder(config.encoder, device=config.device, cache_dir=config.cache_dir)
    splits = select_splits(config)
    train, test = splits.train, splits.test
    memory_dir = (
        config.memory if config.memory is not None else build_training_memory(config, splits, encoder)
    )
    memory = FailureMemory.load(memory_dir)
    check_disjoint(memory, test)
    memory, test = _deploy_successes(memory, test, config.deployment_successes, encoder, config.success_step)
    detector = FailureDetector(memory, encoder, k=config.k)
    thresholds, calibrated, spreads, bands = _thresholds(config, detector, train)
    if bands is not None:  # calibrated here: the test runs are judged on the bands fitted with the thresholds
        detector = FailureDetector(memory, encoder, k=config.k, bands=bands)
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
                trace = detector.run(trajectory, stride=config.stride, keep_queries=False)
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
                    fps=trajectory.fps,
                )
            )
    if not scored:
        raise DataError(
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
            spread=spreads.get(rule),
        )
        for rule, threshold in thresholds.items()
    }
    return EvaluationResult(
        name=config.name,
        encoder=memory.encoder,
        memory=str(memory_dir),
        k=config.k,
        operating_delta=operating,
        calibrated=calibrated.get(PAPER, False),
        rules=rules,
        target_fpr=config.target_fpr if config.target_fpr is not None else _stored_target(memory),
        deployment_successes=config.deployment_successes,
        band=next((band.kind for band in detector.bands.values()), "none"),
        views=views,
        scored=scored,
        traces=traces,
        skipped_unknown_task=skipped,
        latency_ms=measure_latency(detector, first),
        skipped_too_short=too_short,
        skipped_inputs=splits.skipped,
        stride=config.stride,
        vocabulary=memory.vocabulary,
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
            )
        )
        write_evaluation(result, folder)
        points.append(GrowthPoint(level, judged(result.rules, failures=level > 0)))
    points.append(GrowthPoint(None, judged(full.rules, failures=True)))
    return points


def _stored_target(memory: FailureMemory) -> float | None:
    """The α the memory's stored thresholds were calibrated to, if they belong to its encoder."""
    calibration = memory.manifest.calibration
    return calibration.target_for(memory.encoder) if calibration is not None else None


def _deploy_successes(
    memory: FailureMemory, test: list[Trajectory], per_task: int, encoder: CachedEncoder, step: float
) -> tuple[FailureMemory, list[Trajectory]]:
    """Move `per_task` success runs per task from the test set into the success memory (in memory only)."""
    if per_task == 0 or memory.successes is None:
        return memory, test
    chosen: list[Trajectory] = []
    for task in sorted({t.task for t in test}):
        runs = sorted((t for t in test if t.task == task and not t.is_failure), key=lambda t: t.key)
        chosen += runs[:per_task]
    deployed = memory.with_successes(
        memory.successes.extended(SuccessMemory.build(chosen, encoder, step=step))
    )
    keys = {t.key for t in chosen}
    return deployed, [t for t in test if t.key not in keys]


def _thresholds(
    config: EvaluateConfig, detector: FailureDetector, train: Sequence[Trajectory]
) -> tuple[
    dict[ScoringRule, float], dict[ScoringRule, bool], dict[ScoringRule, FprSpread], dict[str, Band] | None
]:
    """Each rule's threshold: conformal on the training successes, or the memory's stored/default one;
    when calibrated here, how far its test FPR can stray with the runs it was set from, and the rules'
    bands (None: the stored thresholds, with the memory's own bands)."""
    from robofailring.evaluation.calibration import available_rules, calibrate_rules

    rules = available_rules(detector)
    if config.target_fpr is None:
        stored = {r: stored_threshold(detector.memory, r) for r in rules}
        return (
            {r: detector.threshold_of(r) for r in rules},
            {r: stored[r] is not None for r in rules},
            {},
            None,
        )
    known = set(detector.memory.tasks)
    successes = [t for t in train if not t.is_failure and t.task in known]
    if not successes:
        raise DataError(
            f"no success trajectory of the memory's tasks in {config.data} (split {config.train_split!r}): "
            "the evaluation calibrates its thresholds on success runs; add success episodes of those tasks "
            "to that split, or name another with --train-split"
        )
    with progress_bar(total=len(successes), desc="calibrating", unit="traj") as bar:
        found = calibrate_rules(
            detector,
            successes,
            config.target_fpr,
            rules=rules,
            progress=bar.update,
            stride=config.stride,
            band=config.band,
        )
    return (
        {r: c.threshold for r, c in found.items()},
        {r: True for r in found},
        {r: c.spread for r, c in found.items()},
        {r.name: c.band for r, c in found.items() if c.band is not None},
    )


def write_evaluation(result: EvaluationResult, out: Path) -> tuple[Path, Path]:
    """evaluation.json and evaluation.md under `out`, written atomically."""
    out = Path(out)
    json_path, md_path = out / f"{result.name}.json", out / f"{result.name}.md"
    write_text_atomic(json_path, json.dumps(result.to_dict(), indent=2))
    write_text_atomic(md_path, result.to_markdown() + "\n")
    return json_path, md_path
