"""The evaluate job: its config (`EvaluateConfig`) and its run (`run_evaluation`, the paper's evaluation, §4:
a memory from the training failures, every test run replayed once, every rule judged at its threshold), with the
steps that read the config (the splits, the memory built from the training split, the learning curve, the
cross-validation). The modules below take the values they need, never this config: the splits and their
disjointness check (`splits.py`), the deployment protocol (`deployment.py`), the thresholds (`thresholds.py`),
the replay (`replay.py`), the folds (`folds.py`) and the learning curve's levels (`growth.py`)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from robofailring.calibration.job import available_rules
from robofailring.calibration.policy import DEFAULT_POLICY, ThresholdPolicy
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.detection.config import (
    DEFAULT_SCORING,
    DEFAULT_STRIDE,
    DetectorConfig,
    Scoring,
    check_stride,
)
from robofailring.detection.detector import FailureDetector
from robofailring.detection.loader import detector_with
from robofailring.detection.rules import PAPER
from robofailring.encoders import CachedEncoder
from robofailring.encoders.placement import DEFAULT_PLACEMENT, EncoderPlacement
from robofailring.errors import SettingError, SplitError
from robofailring.evaluation.deployment import deploy_successes, deployed_runs
from robofailring.evaluation.folds import CrossValidation, FoldPlan, cross_validate
from robofailring.evaluation.folds_alone import FoldsAlone
from robofailring.evaluation.growth import GrowthPoint, judged, labelled_failures
from robofailring.evaluation.latency import measure_latency
from robofailring.evaluation.metrics import PAPER_DELTAS
from robofailring.evaluation.replay import PlaceFor, judge, prefetch_runs, replay
from robofailring.evaluation.result import EvaluationResult
from robofailring.evaluation.splits import Splits, check_disjoint, load_labelled, split_data
from robofailring.evaluation.thresholds import evaluation_thresholds, stored_target
from robofailring.evaluation.written import write_evaluation
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import DEFAULT_RECIPE, MemoryRecipe
from robofailring.outputs import check_file_stem


@dataclass(frozen=True)
class EvaluateConfig:
    data: DataSelection  # the dataset whose training split's failures form the memory, how it is read
    out: Path  # folder for evaluation.json and evaluation.md (and memory/ when built here)
    # the memory built here (encoder, failure frames, pairing, success step); its encoder also opens `memory`
    recipe: MemoryRecipe = DEFAULT_RECIPE
    memory: Path | None = (
        None  # an existing memory (its failures must not be in the test set); None: built here
    )
    # how runs are scored (K, modality; every rule is judged, at thresholds calibrated here or stored)
    scoring: Scoring = DEFAULT_SCORING
    placement: EncoderPlacement = (
        DEFAULT_PLACEMENT  # where the recipe's encoder runs: device, runtime, cache, Ray
    )
    # every rule calibrated here on the training successes (α, band, fusion); None: the memory's stored thresholds
    threshold_policy: ThresholdPolicy | None = DEFAULT_POLICY
    memory_out: Path | None = None  # where a memory built here is saved (default out/memory)
    # a second dataset to test on (e.g. out-of-distribution; `data.other(root, labels=…)` reads it as `data`)
    test_data: DataSelection | None = None
    train_split: str = "train"
    test_split: str = "test"
    test_fraction: float = 0.5  # for datasets without splits: a deterministic hash split
    deltas: tuple[float, ...] = PAPER_DELTAS
    name: str = "evaluation"  # a file name stem: `<name>.json`, `<name>.md`, `<name>.rrd` in `out`
    stride: int = (
        DEFAULT_STRIDE  # score every stride-th frame of a test trajectory (t_det, T_s in original frames)
    )
    success_memory: bool = True  # build the success memory beside the failure memory (contrast rule)
    deployment_successes: int = 0  # per task: test success runs moved into the success memory
    failures_per_task: int | None = None  # the memory built here holds N training failures per task
    # (`labelled_failures`; 0: success runs only, judged by the novelty rule); None: all of them
    folds: FoldPlan | None = None  # also cross-validate over every labelled run of `data` (evaluation.folds)

    def __post_init__(self) -> None:  # bad settings fail before any frame is encoded
        check_stride(self.stride)
        check_file_stem(self.name)  # `<name>.json` and the rest stay inside `out`
        if self.deployment_successes < 0:
            raise SettingError(f"deployment successes must be ≥ 0, got {self.deployment_successes}")
        if self.failures_per_task is not None and self.failures_per_task < 0:
            raise SettingError(f"failures per task must be ≥ 0, got {self.failures_per_task}")
        for delta in self.deltas:
            PAPER.check_threshold(delta)
        if not 0.0 < self.test_fraction < 1.0:
            raise SettingError(f"test fraction must lie in (0, 1), got {self.test_fraction}")
        if self.folds is not None and (self.memory is not None or self.threshold_policy is None):
            raise SettingError(
                "--folds builds a memory and calibrates thresholds per fold from the data: leave out --memory "
                "and give a target FPR"
            )

    @property
    def detector(self) -> DetectorConfig:
        """The detector every rule is judged by: the memory (when given), no rule or threshold of its own."""
        return DetectorConfig(memory=self.memory, scoring=self.scoring, placement=self.placement)


def select_splits(config: EvaluateConfig) -> Splits:
    """The training and test trajectories, disjoint by construction and checked."""
    return split_data(
        config.data,
        config.test_data,
        train_split=config.train_split,
        test_split=config.test_split,
        test_fraction=config.test_fraction,
    )


def evaluation_encoder(config: EvaluateConfig) -> CachedEncoder:
    """The encoder an evaluation builds its memories with: its recipe's, where its placement says (device,
    runtime, cache, Ray cluster)."""
    return config.placement.open(config.recipe.encoder)


def build_training_memory(
    config: EvaluateConfig, splits: Splits | None = None, encoder: CachedEncoder | None = None
) -> tuple[Path, list[Skipped]]:
    """Build the memory from the training split's failures (and successes) and save it to `config.memory_out`;
    its folder and what the build did not use (`BuildStats.skipped_inputs`, kept in its manifest too)."""
    if encoder is None:
        encoder = evaluation_encoder(config)
    if splits is None:
        splits = select_splits(config)
    provenance = Provenance(
        data=config.data.root,
        encoder=config.recipe.encoder,
        layout=splits.dataset.layout,
        views=splits.dataset.views,
        split=config.train_split,
        skipped_inputs=splits.dataset.skipped,
    )
    memory, stats = build_memories(
        labelled_failures(splits.train, config.failures_per_task),
        encoder,
        provenance=provenance,
        recipe=config.recipe,
        successes=config.success_memory,
        vocabulary=config.data.read_vocabulary(),
    )
    memory_dir = config.memory_out or Path(config.out) / "memory"
    memory.save(memory_dir)
    return memory_dir, stats.skipped_inputs


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
        detector, memory_dir, built = _training_detector(config, splits)
    else:
        read_from = detector.memory.read_from
        memory_dir = read_from[0] if read_from is not None else config.detector.memory_dir
    memory, encoder = detector.memory, detector.encoder
    check_disjoint(memory, test)
    calibrating = train if config.threshold_policy is not None else []
    prefetch_runs(encoder, test, calibrating, known=set(memory.tasks), stride=config.stride)
    deployed, test, not_deployed = deploy_successes(
        memory, test, config.deployment_successes, encoder, config.recipe.success_step
    )
    if deployed is not memory:
        memory, detector = deployed, detector_with(config.detector, deployed, encoder)
    thresholds = evaluation_thresholds(
        detector,
        train,
        config.threshold_policy,
        stride=config.stride,
        data_root=config.data.root,
        train_split=config.train_split,
    )
    found = thresholds.found
    if found is not None:  # calibrated here: the test runs are judged on the bands fitted with the thresholds
        detector = detector_with(config.detector, memory, encoder, bands=thresholds.bands)
    replayed = replay(detector, test, stride=config.stride, place=place, desc=f"replaying {config.name}")
    verdicts = judge(replayed, thresholds, memory.vocabulary)
    policy = config.threshold_policy
    return EvaluationResult(
        name=config.name,
        encoder=memory.encoder,
        memory=str(memory_dir),
        k=detector.k,
        # δ, or the paper rule's default where the memory holds no failure (its tables are empty then)
        operating_delta=thresholds.values.get(PAPER, PAPER.default_threshold),
        calibrated=thresholds.calibrated.get(PAPER, False),
        rules=verdicts.rules,
        modalities=verdicts.modalities,
        target_fpr=policy.target_fpr if policy is not None else stored_target(memory),
        deployment_successes=config.deployment_successes,
        band=next((band.kind for band in detector.bands.values()), "none"),
        views=replayed.views,
        scored=replayed.scored,
        traces=verdicts.traces,
        skipped_unknown_task=replayed.unknown_task,
        latency_ms=measure_latency(detector, replayed.first),
        skipped_too_short=replayed.too_short,
        skipped_inputs=list(
            dict.fromkeys(  # each listed once: a run's own skips (its trace's) are among the dataset's too
                [
                    *splits.skipped,
                    *built,
                    *not_deployed,
                    *verdicts.skipped_inputs,
                ]
            )
        ),
        stride=config.stride,
        vocabulary=memory.vocabulary,
        failure_frames=memory.manifest.failure_mode,
        pairing=memory.pairing,
        uncalibrated=[r.name for r in available_rules(detector) if found is not None and r not in found],
        cross_validation=(
            _cross_validation(config, splits.dataset.trajectories(), encoder)
            if config.folds is not None
            else None
        ),
    )


def _training_detector(config: EvaluateConfig, splits: Splits) -> tuple[FailureDetector, Path, list[Skipped]]:
    """The detector of `config` on its memory (built here from the training split, checked for the deployment
    successes first, or the one given), its folder, and what building it did not use."""
    built: list[Skipped] = []
    if config.memory is None:  # the memory built here: checked before it is built
        deployed_runs(
            splits.test,
            config.deployment_successes,
            tasks={t.task for t in splits.train},
            successes=config.success_memory,
        )
    encoder = evaluation_encoder(config)
    if config.memory is not None:
        memory_dir = config.memory
    else:
        memory_dir, built = build_training_memory(config, splits, encoder)
    tested = [selection.root for selection in (config.data, config.test_data) if selection is not None]
    detector = detector_with(config.detector, FailureMemory.load(memory_dir, trusted=tested), encoder)
    return detector, memory_dir, built


def _cross_validation(
    config: EvaluateConfig, trajectories: Iterable[Trajectory], encoder: CachedEncoder
) -> CrossValidation:
    """`config.folds`' cross-validation over `trajectories` (every run of `config.data`)."""
    assert config.folds is not None and config.threshold_policy is not None  # EvaluateConfig checks both
    return cross_validate(
        list(trajectories),
        encoder,
        plan=config.folds,
        data=config.data,
        recipe=config.recipe,
        success_memory=config.success_memory,
        detector=config.detector,
        policy=config.threshold_policy,
        stride=config.stride,
    )


def cross_validate_alone(config: EvaluateConfig, held_out: SplitError) -> FoldsAlone:
    """`config`'s cross-validation (`config.folds`) over every run of `config.data`, for data whose split
    raised `held_out` before any held-out figure was made."""
    if config.folds is None:
        raise held_out
    dataset, _, skipped = load_labelled(config.data, vocabulary=config.data.read_vocabulary())
    return FoldsAlone(
        name=config.name,
        encoder=config.recipe.encoder,
        held_out=str(held_out),
        cross_validation=_cross_validation(config, dataset.trajectories(), evaluation_encoder(config)),
        skipped_inputs=skipped,
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
