"""The main job on the embedded default: simulate, build the memory, calibrate, evaluate, record."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path

import numpy as np

from rfr_viz.charts.report_html import REPORT_NAME, write_report
from rfr_viz.codecs import CameraCodec
from rfr_viz.jobs.compare_encoders import EncoderComparison, run_encoder_comparison
from rfr_viz.jobs.replay import recording_name
from rfr_viz.panels.map import placer
from rfr_viz.panels.umap import memory_map
from rfr_viz.recordings.evaluation import record_evaluation
from rfr_viz.recordings.replay import record_replay
from robofailring.atomic import output_lock, remove_file_leftovers
from robofailring.calibration.job import CalibrateConfig, calibrate
from robofailring.calibration.policy import DEFAULT_POLICY, ThresholdPolicy
from robofailring.data.grounding import failure_type
from robofailring.data.layouts import load_dataset
from robofailring.data.selection import DataSelection
from robofailring.detection.loader import detector_from
from robofailring.detection.rules import CONTRAST, PAPER, ScoringRule
from robofailring.encoders import default_cache_dir
from robofailring.encoders.placement import DEFAULT_PLACEMENT, EncoderPlacement
from robofailring.encoders.training import TrainEncoderConfig
from robofailring.evaluation.job import EvaluateConfig, build_training_memory, run_evaluation
from robofailring.evaluation.per_rule import runs_below_top
from robofailring.evaluation.result import EvaluationResult
from robofailring.evaluation.written import write_evaluation
from robofailring.jobs.compare_encoders import CompareEncodersConfig
from robofailring.jobs.train_encoder import TrainEncoderJob, run_train_encoder
from robofailring.memory.recipe import DEFAULT_ENCODER, DEFAULT_RECIPE, MemoryRecipe
from robofailring.outputs import check_folder, check_output_folder, check_own_files
from robofailring.sim import TASKS, GenerateConfig, simulate


@dataclass(frozen=True)
class DemoConfig:
    out: Path = Path("recordings/demo")  # memory, tables, summary and trajectory recordings
    data_dir: Path | None = None  # simulated datasets (cached); default <cache>/demo-data
    tasks: tuple[str, ...] = TASKS  # simulated tasks
    episodes: int = 3  # in-distribution episodes per task and kind (even: memory, odd: test)
    # in-distribution success runs per task; None: enough that the training half's (every other run's) split-conformal
    # threshold at α sits below its highest calibration peak (α = 0.05: 39 runs, 20 per task over 4 tasks)
    success_episodes: int | None = None
    ood_episodes: int = 1  # out-of-distribution episodes per task and kind (all test)
    image_size: int = 128
    frames: int = 40
    # α: split-conformal calibration of every rule on the training successes (and its band and fusion)
    threshold_policy: ThresholdPolicy = DEFAULT_POLICY
    workers: int = 2
    placement: EncoderPlacement = DEFAULT_PLACEMENT  # where every step's encoder runs: device, cache, …
    camera_codec: CameraCodec = CameraCodec.AUTO  # jpeg, av1, h264, or auto (by size)
    trained_epochs: int = 10  # train-encoder on the ID split (and random looks): the headline (0: none)
    # the memories built (failure frames, pairing, success step), each with its own encoder: the trained
    # one's (the recipe's without training)
    recipe: MemoryRecipe = DEFAULT_RECIPE
    randomize: int = 32  # randomised-look episodes the trained encoder also trains on (0: none)
    # encoders the comparison measures beside the headline and pixels (a pretrained backbone, a CLIP)
    compare_with: tuple[str, ...] = ()


@dataclass
class DemoResult:
    evaluations: list[EvaluationResult]
    summary: Path
    tables: list[Path]
    recordings: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    report: Path | None = None  # report.html: charts, tables and links to the recordings
    # the headline encoder against pixels (and `compare_with`), each calibrated
    comparison: EncoderComparison | None = None
    encoder: str = DEFAULT_ENCODER  # the headline detector's encoder spec


def _pick(result: EvaluationResult, kind: str, rule: ScoringRule) -> tuple[str, int] | None:
    """A trajectory key and its focus frame for one kind of outcome under `rule`, or None when there is none."""
    threshold = result.rules[rule.name].threshold
    scored_by_rule = result.rule_scored(rule)
    if (
        kind == "detection"
    ):  # clean: the nearest entry has the true failure type, and the score rose after frame 0
        hits = []
        for scored in scored_by_rule:
            t_det = scored.t_det(threshold)
            if scored.is_failure and t_det is not None:
                trace = result.rule_trace(scored.key, rule)
                view = trace.camera_at(trace.detected_view, t_det)
                found = trace.neighbors(view, t_det) if view is not None else []
                top = found[0] if found else None
                same_type = top is not None and failure_type(top.entry.symbol) == failure_type(scored.symbol)
                hits.append((not same_type, t_det == 0, t_det / max(scored.length, 1), scored.key, t_det))
        return (min(hits)[3], min(hits)[4]) if hits else None
    if kind == "false-alarm":
        alarms = [(s.t_det(threshold) or 0, s.key) for s in scored_by_rule if not s.is_failure]
        alarms = [(t, key) for t, key in alarms if key in result.rules[rule.name].false_alarms]
        return (alarms[0][1], alarms[0][0]) if alarms else None
    misses = sorted(
        (s for s in scored_by_rule if s.key in result.rules[rule.name].misses),
        key=lambda s: -float(s.peak()),
    )
    return (misses[0].key, int(np.argmax(misses[0].scores()))) if misses else None


def demo_successes(config: DemoConfig) -> int:
    """The in-distribution success runs per task the demo simulates (`DemoConfig.success_episodes`)."""
    if config.success_episodes is not None:
        return config.success_episodes
    return math.ceil(2 * runs_below_top(config.threshold_policy.target_fpr) / len(config.tasks))


def simulate_datasets(config: DemoConfig, data_dir: Path) -> tuple[Path, Path]:
    """The in- and out-of-distribution sets under `data_dir`, simulated once and reused while their recipe holds."""
    simulated = GenerateConfig(
        out=data_dir / "sim-id",
        tasks=config.tasks,
        episodes=config.episodes,
        success_episodes=demo_successes(config),
        seed=0,
        image_size=config.image_size,
        frames=config.frames,
        workers=config.workers,
    )
    in_dist = simulate(simulated, label="ID")
    out_dist = simulate(
        replace(
            simulated,
            out=data_dir / "sim-ood",
            episodes=config.ood_episodes,
            success_episodes=2 * config.ood_episodes,
            seed=1000,
            ood=True,
        ),
        label="OOD",
    )
    return in_dist, out_dist


def run_demo(config: DemoConfig, *, say: Callable[[str], None] = print) -> DemoResult:
    """Generate (cached) in- and out-of-distribution sets, then memory, calibration, evaluation, recordings."""
    data_dir = config.data_dir or default_cache_dir() / "demo-data"
    check_output_folder(config.out, inputs=[data_dir])
    with output_lock(config.out):
        remove_file_leftovers(config.out)
        names = (
            "in-distribution.json",
            "in-distribution.md",
            "out-of-distribution.json",
            "out-of-distribution.md",
        )
        check_own_files(Path(config.out) / name for name in (*names, REPORT_NAME))
        check_folder(data_dir, holds="the demo's cache of simulated datasets", flag="--data-dir")
        return _run_demo(config, data_dir, say)


def _run_demo(config: DemoConfig, data_dir: Path, say: Callable[[str], None]) -> DemoResult:
    out = Path(config.out)
    in_dist, out_dist = simulate_datasets(config, data_dir)
    say(f"datasets: {in_dist} (in-distribution), {out_dist} (out-of-distribution)")
    encoder = _headline_encoder(config, in_dist, data_dir, say)
    say(
        f"detector: encoder {encoder}, {config.recipe.failure_frames} failure memory, {config.recipe.pairing} pairing, "
        f"contrast rule on a time-indexed band, calibrated to α = {config.threshold_policy.target_fpr:g} (the paper's rule beside "
        "it; pixels in encoders/comparison.md)"
    )

    base = EvaluateConfig(
        data=DataSelection(in_dist),
        out=out,
        recipe=replace(config.recipe, encoder=encoder),
        placement=config.placement,
        memory_out=out / "memory",
    )
    memory_dir, _ = build_training_memory(base)  # its skips: in its manifest (simulated runs have none)
    calibration = calibrate(
        CalibrateConfig(
            data=base.data,
            memory=memory_dir,
            placement=config.placement,
            threshold_policy=config.threshold_policy,
        )
    )
    say(
        f"memory {memory_dir}: split-conformal thresholds for FPR ≤ {100 * config.threshold_policy.target_fpr:g} % on "
        f"{calibration.successes} training successes ({calibration.encoder}): paper δ = {calibration.delta:.4f}, "
        f"contrast γ = {calibration.gamma if calibration.gamma is not None else float('nan'):.4f}"
    )
    # the thresholds calibration just stored; the memory loaded once, for both evaluations and every recording
    stored = replace(base, memory=memory_dir, threshold_policy=None)
    detector = detector_from(stored.detector, trusted=[stored.data.root])
    mapped = memory_map(detector.memory, directory=memory_dir)
    place = partial(placer, mapped)  # the recordings' map points, placed while the evaluations score
    evaluations = [
        run_evaluation(replace(stored, name="in-distribution"), detector=detector, place=place),
        run_evaluation(
            replace(
                stored, name="out-of-distribution", test_data=base.data.other(out_dist), test_split="ood"
            ),
            detector=detector,
            place=place,
        ),
    ]
    for evaluation in evaluations:
        rows = sorted(evaluation.rules.values(), key=lambda row: row.rule is PAPER)  # the paper's last
        for row in rows:
            say(
                f"{evaluation.name}, {row.rule.name} rule ({row.rule.symbol} = {row.threshold:.4f}): recall "
                f"{100 * row.recall:.1f} %, FPR {100 * row.fpr:.1f} %, mean T_s "
                f"{'—' if np.isnan(row.ts_mean) else f'{100 * row.ts_mean:.1f} %'}, "
                f"AUC {row.auc:.3f}"
            )
    rule = CONTRAST if CONTRAST.name in evaluations[0].rules else PAPER
    tables = [path for result in evaluations for path in write_evaluation(result, out)]
    summary = record_evaluation(evaluations, out=out / "evaluation.rrd")
    result = DemoResult(evaluations=evaluations, summary=summary, tables=tables, encoder=encoder)

    sources = {"in-distribution": in_dist, "out-of-distribution": out_dist}
    for kind in ("detection", "false-alarm", "miss"):
        for evaluation in evaluations:
            picked = _pick(evaluation, kind, rule)
            if picked is None:
                continue
            key, focus = picked
            (trajectory,) = load_dataset(sources[evaluation.name]).select(keys=[key])
            path = out / "recordings" / f"{kind}__{evaluation.name}__{recording_name(trajectory)}"
            result.recordings[kind] = record_replay(
                trajectory,
                evaluation.rule_trace(key, rule),  # as the evaluation scored it, its queries on the map
                out=path,
                memory_map=mapped,
                focus_frame=focus,
                camera_codec=config.camera_codec,
            )
            break
        else:
            result.notes.append(
                f"no {kind.replace('-', ' ')} occurred under the calibrated {rule.name} rule in either split"
            )
    result.report = write_report(
        [e.to_dict() for e in evaluations],
        out / REPORT_NAME,
        markdown=[e.to_markdown() for e in evaluations],
        recordings={"evaluation summary": summary} | result.recordings,
        title="RoboFailRing demo: simulated FailGen, in and out of distribution",
    )
    if encoder != DEFAULT_ENCODER or config.compare_with:
        result.comparison = _compare_encoders(config, in_dist, out, encoder, evaluations[0])
    return result


def _headline_encoder(config: DemoConfig, in_dist: Path, data_dir: Path, say: Callable[[str], None]) -> str:
    """The encoder the demo leads with: the trained one (trained or reused), else the recipe's (pixels)."""
    if not config.trained_epochs:
        return config.recipe.encoder
    return f"trained:{_trained_encoder(config, in_dist, data_dir, say)}"


def _compare_encoders(
    config: DemoConfig, in_dist: Path, out: Path, encoder: str, headline: EvaluationResult
) -> EncoderComparison:
    """The headline encoder against the weight-free pixels one and `config.compare_with`, each calibrated
    at the demo's α: the headline's in-distribution evaluation is the comparison's own (built, calibrated
    and scored once)."""
    return run_encoder_comparison(
        CompareEncodersConfig(
            data=DataSelection(in_dist),
            out=out / "encoders",
            encoders=tuple(dict.fromkeys((encoder, DEFAULT_ENCODER, *config.compare_with))),
            threshold_policy=config.threshold_policy,  # each encoder calibrated at the demo's α
            recipe=config.recipe,
            placement=config.placement,
        ),
        existing={encoder: headline},
    )


def _trained_encoder(config: DemoConfig, in_dist: Path, data_dir: Path, say: Callable[[str], None]) -> Path:
    """The encoder trained on the ID training split and `config.randomize` randomised-look episodes
    (simulated beside the demo's sets), trained once and reused while its recipe and frames hold."""
    training = TrainEncoderConfig(
        data=DataSelection(in_dist), out=data_dir / "trained-encoder", epochs=config.trained_epochs
    )
    job = TrainEncoderJob(
        training, randomize=config.randomize, workers=config.workers, sim_cache=data_dir / "randomized"
    )
    return run_train_encoder(job, reuse=True, say=say)
