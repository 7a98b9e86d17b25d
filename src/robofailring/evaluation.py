"""The paper's evaluation (§4): memory from training failures, Recall/FPR sweep, T_s, ablations, review."""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robofailring.atomic import write_text_atomic
from robofailring.data.layouts import load_dataset
from robofailring.data.model import Skipped, Trajectory
from robofailring.detector import (
    PAPER_DELTA,
    DetectionTrace,
    FailureDetector,
    check_delta,
    check_k,
    check_stride,
)
from robofailring.encoders import CachedEncoder, load_encoder
from robofailring.errors import DataError, RoboFailRingError, SettingError
from robofailring.grounding import failure_type
from robofailring.memory import FailureMemory
from robofailring.metrics import (
    PAPER_DELTAS,
    Rates,
    ScoredTrajectory,
    check_target_fpr,
    fine_grid,
    rates,
    sweep,
    timeliness,
)
from robofailring.progress import progress_bar
from robofailring.references import absolute_reference
from robofailring.rule_evaluation import MARKDOWN_HEADER, RuleResult, evaluate_rule, scored_by_rule
from robofailring.scoring import ScoreRule
from robofailring.success_memory import SuccessMemory
from robofailring.thinning import DEFAULT_STEP


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
    target_fpr: float | None = 0.05  # calibrate both rules on training successes; None: stored thresholds
    successes: bool = True  # build the success memory beside the failure memory (contrast rule)
    success_step: float = (
        DEFAULT_STEP  # thinning of success runs (robofailring.thinning); 0 keeps every frame
    )
    deployment_successes: int = 0  # per task: test success runs moved into the success memory

    def __post_init__(self) -> None:  # bad settings fail before any frame is encoded
        check_k(self.k)
        check_stride(self.stride)
        if self.target_fpr is not None:
            check_target_fpr(self.target_fpr)
        if self.deployment_successes < 0:
            raise SettingError(f"deployment successes must be ≥ 0, got {self.deployment_successes}")
        for delta in self.deltas:
            check_delta(delta)
        if not 0.0 < self.test_fraction < 1.0:
            raise SettingError(f"test fraction must lie in (0, 1), got {self.test_fraction}")


def _hash_split(trajectory: Trajectory, test_fraction: float) -> str:
    digest = hashlib.blake2b(trajectory.key.encode(), digest_size=8).digest()
    return "test" if int.from_bytes(digest, "big") / 2**64 < test_fraction else "train"


def split_of(trajectory: Trajectory, *, has_splits: bool, test_fraction: float) -> str:
    """The trajectory's split from its dataset, or a deterministic hash split when there is none."""
    if has_splits:
        return trajectory.split or ""
    return _hash_split(trajectory, test_fraction)


def select_splits(
    config: EvaluateConfig, skipped: list[Skipped] | None = None
) -> tuple[list[Trajectory], list[Trajectory]]:
    """(training trajectories, test trajectories), disjoint by construction and checked.

    What the datasets' loaders did not read is appended to `skipped`.
    """
    dataset = load_dataset(config.data, labels=config.labels)
    dataset.require_labels("evaluate")
    source = list(dataset.trajectories())
    if skipped is not None:
        skipped += dataset.skipped
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
        other_dataset = load_dataset(config.test_data, labels=config.labels)
        other_dataset.require_labels("evaluate")
        other = list(other_dataset.trajectories())
        if skipped is not None:
            skipped += other_dataset.skipped
        other_has_splits = any(t.split for t in other)
        test = [t for t in other if not other_has_splits or t.split == config.test_split]
    if not test:
        raise DataError(
            f"no test trajectories (split {config.test_split!r}) in {config.test_data or config.data}"
        )
    return train, test


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


@dataclass
class EvaluationResult:
    """Everything the evaluation measured, for the tables, the JSON file and the summary recording."""

    name: str
    encoder: str
    memory: str
    k: int
    operating_delta: float
    calibrated: bool
    views: list[str]
    scored: list[ScoredTrajectory] = field(repr=False)
    traces: dict[str, DetectionTrace] = field(repr=False)
    skipped_unknown_task: list[str]
    latency_ms: dict[str, float]
    skipped_too_short: list[str] = field(default_factory=list)
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the data not read
    stride: int = 1
    rules: dict[str, RuleResult] = field(default_factory=dict)  # both rules at their thresholds
    target_fpr: float | None = None
    deployment_successes: int = 0
    paper_rates: list[Rates] = field(init=False)
    curve: list[Rates] = field(init=False)

    def __post_init__(self) -> None:
        self.paper_rates = sweep(self.scored, PAPER_DELTAS)
        self.curve = sweep(self.scored, fine_grid(self.scored))

    @property
    def failures(self) -> int:
        return sum(t.is_failure for t in self.scored)

    @property
    def successes(self) -> int:
        return sum(not t.is_failure for t in self.scored)

    def rule_trace(self, key: str, rule: ScoreRule) -> DetectionTrace:
        """A test trajectory's trace judged by `rule` at its evaluated threshold."""
        return self.traces[key].with_rule(rule, self.rules[rule.value].threshold)

    def rule_scored(self, rule: ScoreRule) -> list[ScoredTrajectory]:
        """The test trajectories with `rule`'s score (S_t or C_t) per view."""
        return scored_by_rule(self.traces, {t.key: t for t in self.scored}, rule)

    def per_type_recall(
        self, delta: float, scored: Sequence[ScoredTrajectory] | None = None
    ) -> dict[str, Rates]:
        """Recall per failure type at `delta` (of `scored`: another rule's scores; default the paper's)."""
        scored = self.scored if scored is None else scored
        types = sorted({failure_type(t.symbol) for t in scored if t.is_failure and t.symbol})
        return {
            kind: rates([t for t in scored if t.is_failure and failure_type(t.symbol) == kind], delta)
            for kind in types
        }

    def view_ablation(
        self, delta: float, scored: Sequence[ScoredTrajectory] | None = None
    ) -> dict[str, Rates]:
        scored = self.scored if scored is None else scored
        ablation = {view: rates(scored, delta, [view]) for view in self.views}
        ablation["fusion"] = rates(scored, delta)
        return ablation

    def rule_charts(self, rule: ScoreRule, rate_row: Callable[[Rates], dict[str, Any]]) -> dict[str, Any]:
        """A rule's own sweep, recall per type and per view, and detection progress at its threshold."""
        scored = self.rule_scored(rule)
        threshold = self.rules[rule.value].threshold
        counts, edges = timeliness(scored, threshold).histogram()
        return {
            "operating_threshold": threshold,
            "sweep": [rate_row(r) for r in sweep(scored, fine_grid(scored))],
            "recall_per_type": {k: rate_row(v) for k, v in self.per_type_recall(threshold, scored).items()},
            "view_ablation": {k: rate_row(v) for k, v in self.view_ablation(threshold, scored).items()},
            "progress_histogram": {"threshold": threshold, "counts": counts, "edges": edges},
        }

    def false_alarms(self, delta: float) -> list[ScoredTrajectory]:
        return [t for t in self.scored if not t.is_failure and t.t_det(delta) is not None]

    def misses(self, delta: float) -> list[ScoredTrajectory]:
        return [t for t in self.scored if t.is_failure and t.t_det(delta) is None]

    def false_alarm_entries(self, delta: float) -> list[dict[str, Any]]:
        """Memory entries that were the top neighbour at a false alarm, most culpable first."""
        blame: Counter[int] = Counter()
        for scored in self.false_alarms(delta):
            trace = self.traces[scored.key].with_delta(delta)
            view, t_det = trace.detected_view, trace.t_det
            if view is not None and t_det is not None:
                for neighbor in trace.neighbors(view, t_det)[:1]:
                    blame[neighbor.index] += 1
        memory = next(iter(self.traces.values())).memory if self.traces else None
        rows = []
        for index, count in blame.most_common():
            assert memory is not None
            entry = memory.entries[index]
            rows.append(
                {
                    "index": index,
                    "false_alarms": count,
                    "task": entry.task,
                    "symbol": entry.symbol,
                    "episode": entry.episode,
                    "view": entry.view,
                }
            )
        return rows

    def to_dict(self) -> dict[str, Any]:
        delta = self.operating_delta
        time_at = timeliness(self.scored, delta)
        counts, edges = time_at.histogram()

        def rate_row(r: Rates) -> dict[str, Any]:
            return {
                "delta": r.delta,
                "recall": _num(r.recall),
                "fpr": _num(r.fpr),
                "tp": r.tp,
                "fn": r.fn,
                "fp": r.fp,
                "tn": r.tn,
            }

        return {
            "name": self.name,
            "encoder": self.encoder,
            "memory": self.memory,
            "k": self.k,
            "operating_delta": delta,
            "calibrated": self.calibrated,
            "failures": self.failures,
            "successes": self.successes,
            "skipped_unknown_task": self.skipped_unknown_task,
            "skipped_too_short": self.skipped_too_short,
            "skipped_inputs": [skipped.to_dict() for skipped in self.skipped_inputs],
            "stride": self.stride,
            "paper_deltas": [rate_row(r) for r in self.paper_rates],
            "sweep": [rate_row(r) for r in self.curve],
            "timeliness": {
                str(d): {
                    "detected_failures": timeliness(self.scored, d).count,
                    "mean_progress": _num(timeliness(self.scored, d).mean_progress),
                    "median_progress": _num(timeliness(self.scored, d).median_progress),
                    "mean_saving": _num(timeliness(self.scored, d).mean_saving),
                    "median_saving": _num(timeliness(self.scored, d).median_saving),
                }
                for d in (*PAPER_DELTAS, delta)
            },
            "progress_histogram": {
                "delta": delta,
                "counts": counts,
                "edges": edges,
                "values": list(time_at.progress),
            },
            "recall_per_type": {k: rate_row(v) for k, v in self.per_type_recall(delta).items()},
            "view_ablation": {k: rate_row(v) for k, v in self.view_ablation(delta).items()},
            "latency_ms": self.latency_ms,
            "target_fpr": self.target_fpr,
            "deployment_successes": self.deployment_successes,
            "rules": {
                name: result.to_dict() | self.rule_charts(result.rule, rate_row)
                for name, result in self.rules.items()
            },
            "false_alarms": [
                {"key": t.key, "t_det": t.t_det(delta), "length": t.length} for t in self.false_alarms(delta)
            ],
            "misses": [
                {"key": t.key, "symbol": t.symbol, "peak": _num(float(t.scores().max())), "length": t.length}
                for t in self.misses(delta)
            ],
            "false_alarm_entries": self.false_alarm_entries(delta),
            "trajectories": [
                {
                    "key": t.key,
                    "task": t.task,
                    "symbol": t.symbol,
                    "failure": t.is_failure,
                    "length": t.length,
                    "t_det": t.t_det(delta),
                    "peak": _num(float(t.scores().max())),
                }
                for t in self.scored
            ],
        }

    def to_markdown(self) -> str:
        delta = self.operating_delta
        lines = [
            f"## {self.name} — encoder `{self.encoder}`, K = {self.k}",
            "",
            f"{self.failures} failure and {self.successes} success test trajectories; memory `{self.memory}`; "
            f"operating δ = {delta:.4f} ({'calibrated' if self.calibrated else 'paper default'}).",
            "",
            *self._rules_markdown(),
            "| δ | Recall (%) | FPR (%) | TP | FN | FP | TN | mean T_s (%) | median progress (%) |",
            "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        shown = list(self.paper_rates)
        if all(abs(r.delta - delta) > 1e-9 for r in shown):
            shown.append(rates(self.scored, delta))
        for r in shown:
            t = timeliness(self.scored, r.delta)
            lines.append(
                f"| {r.delta:.4g} | {_pct(r.recall)} | {_pct(r.fpr)} | {r.tp} | {r.fn} | {r.fp} | {r.tn} | "
                f"{_pct(t.mean_saving)} | {_pct(t.median_progress)} |"
            )
        time_at = timeliness(self.scored, delta)
        lines += [
            "",
            f"Timeliness at δ = {delta:.4g}: {time_at.count} detected failures, mean detection progress "
            f"{_pct(time_at.mean_progress)} %, median {_pct(time_at.median_progress)} %, "
            f"temporal saving T_s mean {_pct(time_at.mean_saving)} %, median {_pct(time_at.median_saving)} %.",
            "",
            "| failure type | Recall (%) | detected / total |",
            "|---|---:|---:|",
        ]
        for kind, r in self.per_type_recall(delta).items():
            lines.append(f"| {kind} | {_pct(r.recall)} | {r.tp} / {r.tp + r.fn} |")
        lines += ["", "| views | Recall (%) | FPR (%) |", "|---|---:|---:|"]
        for view, r in self.view_ablation(delta).items():
            lines.append(f"| {view} | {_pct(r.recall)} | {_pct(r.fpr)} |")
        lines += [
            "",
            f"Per-frame latency ({len(self.views)} views): encoder {self.latency_ms.get('encode', float('nan')):.2f} ms, "
            f"retrieval {self.latency_ms.get('retrieval', float('nan')):.3f} ms, "
            f"total {self.latency_ms.get('total', float('nan')):.2f} ms.",
        ]
        blamed = self.false_alarm_entries(delta)
        if blamed:
            lines += [
                "",
                "Memory entries behind the most false alarms (candidates to prune):",
                "",
                "| entry | false alarms | task | symbol | episode | view |",
                "|---:|---:|---|---|---|---|",
            ]
            for row in blamed[:10]:
                lines.append(
                    f"| {row['index']} | {row['false_alarms']} | {row['task']} | `{row['symbol']}` | "
                    f"{row['episode']} | {row['view']} |"
                )
        if self.skipped_too_short:
            lines += [
                "",
                f"Skipped {len(self.skipped_too_short)} test trajectories with no view of 2 or more frames.",
            ]
        if self.skipped_inputs:
            lines += ["", f"Not read from the data ({len(self.skipped_inputs)}):", ""]
            lines += [f"- `{skipped.path}`: {skipped.reason}" for skipped in self.skipped_inputs[:20]]
            if len(self.skipped_inputs) > 20:
                lines.append(f"- … and {len(self.skipped_inputs) - 20} more (all in the JSON file)")
        if self.stride > 1:
            lines += [
                "",
                f"Every {self.stride}th frame scored (frame numbers, t_det and T_s are original frames).",
            ]
        if self.skipped_unknown_task:
            lines += [
                "",
                f"Skipped {len(self.skipped_unknown_task)} test trajectories whose task has no memory entry.",
            ]
        return "\n".join(lines)

    def _rules_markdown(self) -> list[str]:
        if not self.rules:
            return []
        deployed = (
            f" {self.deployment_successes} success run(s) per task from the test data joined the success "
            "memory (deployment successes) and are not tested."
            if self.deployment_successes
            else ""
        )
        return [
            "Both scoring rules, each calibrated on the training successes (split conformal, each run's own "
            f"episode left out):{deployed}",
            "",
            MARKDOWN_HEADER,
            *(result.markdown_row(self.target_fpr) for result in self.rules.values()),
            "",
            "The tables below are the paper rule (S_t ≥ δ).",
            "",
        ]


def _num(value: float) -> float | None:
    return None if math.isnan(value) else round(value, 6)


def _pct(value: float) -> str:
    return "—" if math.isnan(value) else f"{100 * value:.2f}"


def measure_latency(
    detector: FailureDetector, trajectory: Trajectory, *, frames: int = 8
) -> dict[str, float]:
    """Per-frame detection latency on real frames, uncached: encode all views, then retrieve."""
    views = [v for v, f in trajectory.views.items() if len(f) >= 2]
    count = min(frames, trajectory.length)
    images = [[trajectory.views[v][t].load() for v in views] for t in range(count)]
    raw = detector.encoder.encoder
    raw.encode(images[0])  # warm-up
    session = detector.session(trajectory.task)
    encode_ms, total_ms = [], []
    for step_images in images:
        start = time.perf_counter()
        raw.encode(step_images)
        encode_ms.append((time.perf_counter() - start) * 1000)
        start = time.perf_counter()
        session.step(dict(zip(views, step_images, strict=True)))
        total_ms.append((time.perf_counter() - start) * 1000)
    encode, total = float(np.median(encode_ms)), float(np.median(total_ms))
    return {"encode": encode, "retrieval": max(total - encode, 0.0), "total": total}


def build_training_memory(
    config: EvaluateConfig, train: Sequence[Trajectory] | None = None, encoder: CachedEncoder | None = None
) -> Path:
    """Build the memory from the training split's failures and save it to `config.memory_out`."""
    if encoder is None:
        encoder = CachedEncoder(
            load_encoder(config.encoder, device=config.device), cache_dir=config.cache_dir
        )
    if train is None:
        train, _ = select_splits(config)
    failures = [t for t in train if t.is_failure]
    with progress_bar(total=sum(len(t.views) for t in failures), desc="memory", unit="entry") as bar:
        memory, _ = FailureMemory.build(failures, encoder, progress=bar.update)
    if config.successes:
        with progress_bar(total=len(train), desc="success memory", unit="traj") as bar:
            built = SuccessMemory.build(train, encoder, progress=bar.update, step=config.success_step)
        memory.successes = built if built.success_runs else None  # no success run: the paper's memory
    memory.manifest.update(
        {
            "source": str(Path(config.data).resolve()),
            "split": config.train_split,
            "encoder_spec": config.encoder,
        }
    )
    memory_dir = config.memory_out or Path(config.out) / "memory"
    memory.save(memory_dir)
    return memory_dir


def run_evaluation(config: EvaluateConfig) -> EvaluationResult:
    """Build (or load) the memory, replay every test trajectory once, and measure everything."""
    encoder = CachedEncoder(load_encoder(config.encoder, device=config.device), cache_dir=config.cache_dir)
    unread: list[Skipped] = []
    train, test = select_splits(config, unread)
    memory_dir = config.memory if config.memory is not None else build_training_memory(config, train, encoder)
    memory = FailureMemory.load(memory_dir)
    check_disjoint(memory, test)
    test = _deploy_successes(memory, test, config.deployment_successes, encoder, config.success_step)
    detector = FailureDetector(memory, encoder, k=config.k)
    thresholds, calibrated = _thresholds(config, detector, train)
    operating = thresholds[ScoreRule.PAPER]
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
                trace = detector.run(trajectory, stride=config.stride)
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
                )
            )
    if not scored:
        raise DataError(
            f"none of the {len(test)} test trajectories has a task in the memory ({sorted(known)})"
        )
    views = sorted({v for s in scored for v in s.similarity})
    first = next(t for t in test if t.key in traces)
    traces = {  # the paper rule at δ, γ kept beside it: the paper tables below read these traces
        key: DetectionTrace(
            **{
                **trace.__dict__,
                "rule": ScoreRule.PAPER,
                "delta": operating,
                "gamma": thresholds.get(ScoreRule.CONTRAST, trace.gamma),
            }
        )
        for key, trace in traces.items()
    }
    labels = {t.key: t for t in scored}
    rules = {
        rule.value: evaluate_rule(
            scored_by_rule(traces, labels, rule), rule, threshold, calibrated=calibrated[rule]
        )
        for rule, threshold in thresholds.items()
    }
    return EvaluationResult(
        name=config.name,
        encoder=memory.encoder,
        memory=str(memory_dir),
        k=config.k,
        operating_delta=operating,
        calibrated=calibrated[ScoreRule.PAPER],
        rules=rules,
        target_fpr=config.target_fpr if config.target_fpr is not None else _stored_target(memory),
        deployment_successes=config.deployment_successes,
        views=views,
        scored=scored,
        traces=traces,
        skipped_unknown_task=skipped,
        latency_ms=measure_latency(detector, first),
        skipped_too_short=too_short,
        skipped_inputs=unread,
        stride=config.stride,
    )


def _stored_target(memory: FailureMemory) -> float | None:
    """The α the memory's stored thresholds were calibrated to, if they belong to its encoder."""
    calibration = memory.manifest.get("calibration") or {}
    target = calibration.get("target_fpr")
    return (
        float(target) if calibration.get("encoder") == memory.encoder and isinstance(target, float) else None
    )


def _deploy_successes(
    memory: FailureMemory, test: list[Trajectory], per_task: int, encoder: CachedEncoder, step: float
) -> list[Trajectory]:
    """Move `per_task` success runs per task from the test set into the success memory (in memory only)."""
    if per_task == 0 or memory.successes is None:
        return test
    chosen: list[Trajectory] = []
    for task in sorted({t.task for t in test}):
        runs = sorted((t for t in test if t.task == task and not t.is_failure), key=lambda t: t.key)
        chosen += runs[:per_task]
    memory.successes = memory.successes.extended(SuccessMemory.build(chosen, encoder, step=step))
    keys = {t.key for t in chosen}
    return [t for t in test if t.key not in keys]


def _thresholds(
    config: EvaluateConfig, detector: FailureDetector, train: Sequence[Trajectory]
) -> tuple[dict[ScoreRule, float], dict[ScoreRule, bool]]:
    """Each rule's threshold: conformal on the training successes, or the memory's stored/default one."""
    from robofailring.calibration import available_rules, calibrate_rules

    rules = available_rules(detector)
    defaults = {ScoreRule.PAPER: detector.delta, ScoreRule.CONTRAST: detector.gamma}
    if config.target_fpr is None:
        stored = {
            ScoreRule.PAPER: detector.memory.calibrated_delta,
            ScoreRule.CONTRAST: detector.memory.calibrated_gamma,
        }
        return {r: defaults[r] for r in rules}, {r: stored[r] is not None for r in rules}
    known = set(detector.memory.tasks)
    successes = [t for t in train if not t.is_failure and t.task in known]
    with progress_bar(total=len(successes), desc="calibrating", unit="traj") as bar:
        found = calibrate_rules(
            detector, successes, config.target_fpr, rules=rules, progress=bar.update, stride=config.stride
        )
    return {r: c.threshold for r, c in found.items()}, {r: True for r in found}


def write_evaluation(result: EvaluationResult, out: Path) -> tuple[Path, Path]:
    """evaluation.json and evaluation.md under `out`, written atomically."""
    out = Path(out)
    json_path, md_path = out / f"{result.name}.json", out / f"{result.name}.md"
    write_text_atomic(json_path, json.dumps(result.to_dict(), indent=2))
    write_text_atomic(md_path, result.to_markdown() + "\n")
    return json_path, md_path


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

    def __post_init__(self) -> None:  # bad settings fail before any frame is encoded
        check_k(self.k)
        check_stride(self.stride)
        check_target_fpr(self.target_fpr)


@dataclass(frozen=True)
class Calibration:
    delta: float
    target_fpr: float
    achieved_fpr: float
    successes: int
    encoder: str
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the data not read
    gamma: float | None = None  # the contrast rule's γ, when the memory has success runs
    gamma_achieved_fpr: float | None = None


def calibrate(config: CalibrateConfig, *, progress: Callable[[int], None] | None = None) -> Calibration:
    """Set δ and γ (split conformal, level = target FPR) on success runs and store them in the manifest."""
    from robofailring.calibration import calibrate_rules
    from robofailring.pipeline import encoder_spec_for

    memory = FailureMemory.load(config.memory)
    encoder = CachedEncoder(
        load_encoder(encoder_spec_for(memory), device=config.device), cache_dir=config.cache_dir
    )
    detector = FailureDetector(memory, encoder, delta=PAPER_DELTA, k=config.k, rule=ScoreRule.PAPER)
    dataset = load_dataset(config.data, labels=config.labels)
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
    with progress_bar(total=len(successes), desc="calibrating", unit="traj") as bar:

        def advance(count: int) -> None:
            bar.update(count)
            if progress is not None:
                progress(count)

        found = calibrate_rules(
            detector, successes, config.target_fpr, progress=advance, stride=config.stride
        )
    paper, contrast = found[ScoreRule.PAPER], found.get(ScoreRule.CONTRAST)
    memory.manifest["calibration"] = {
        "encoder": memory.encoder,
        "delta": paper.threshold,
        "gamma": contrast.threshold if contrast is not None else None,
        "method": "split conformal, own episode left out",
        "target_fpr": config.target_fpr,
        "achieved_fpr": paper.achieved_fpr,
        "gamma_achieved_fpr": contrast.achieved_fpr if contrast is not None else None,
        "successes": paper.successes,
        "data": str(Path(config.data).resolve()),
        "split": config.split,
        "k": config.k,
        "stride": config.stride,
    }
    memory.write_manifest(config.memory)
    return Calibration(
        delta=paper.threshold,
        target_fpr=config.target_fpr,
        achieved_fpr=paper.achieved_fpr,
        successes=paper.successes,
        encoder=memory.encoder,
        skipped_inputs=dataset.skipped,
        gamma=contrast.threshold if contrast is not None else None,
        gamma_achieved_fpr=contrast.achieved_fpr if contrast is not None else None,
    )
