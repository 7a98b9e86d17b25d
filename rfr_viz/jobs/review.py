"""False-positive (and miss) review: replay only the false alarms or the misses of an evaluation."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import numpy as np

from rfr_viz.jobs.replay import DEFAULT_OUT, ReplayResult, load_detector, recording_name
from rfr_viz.panels.camera_video import CameraCodec
from rfr_viz.recordings.replay import record_replay
from robofailring.atomic import output_lock, remove_file_leftovers
from robofailring.data.layouts import load_dataset
from robofailring.detection.rules import CONTRAST, NOVELTY, PAPER, ScoringRule, rule_named
from robofailring.errors import DataError
from robofailring.explain.vlm import VLMConfig
from robofailring.outputs import check_output_folder, check_recording_file
from robofailring.progress import progress_bar

KINDS: Final[tuple[str, ...]] = ("false-alarms", "misses")


@dataclass(frozen=True)
class ReviewConfig:
    evaluation: Path  # the <name>.json written by `robofailring evaluate`
    data: Path  # the dataset that evaluation tested on
    kind: str = "false-alarms"  # "false-alarms" (successes that fired) or "misses" (failures that did not)
    out: Path = DEFAULT_OUT / "review"
    memory: Path | None = None  # default: the memory the evaluation used
    score: str | None = None  # the rule whose alarms to review (default: contrast when evaluated, else paper)
    cache_dir: Path | None = None
    device: str | None = None
    data_root: Path | None = None  # where the memory's images are now, when its data moved
    vlm: VLMConfig | None = None  # ask this VLM about each alarm; its answer joins the report
    camera_codec: CameraCodec = CameraCodec.AUTO  # jpeg, av1, h264, or auto (by size)


def review(config: ReviewConfig) -> ReplayResult:
    """One recording per false alarm (focused on the alarm) or per miss (focused on its peak S_t)."""
    if config.kind not in KINDS:
        raise DataError(f"review kind {config.kind!r} is not one of {list(KINDS)}")
    try:
        evaluation = json.loads(Path(config.evaluation).read_text(encoding="utf-8"))
        rules = evaluation.get("rules") or {}
        shown = next((r.name for r in (CONTRAST, NOVELTY) if r.name in rules), PAPER.name)
        rule = rule_named(config.score or shown)
        field = "false_alarms" if config.kind == "false-alarms" else "misses"
        if rule.name in rules:
            keys = list(rules[rule.name][field])
            threshold = float(rules[rule.name]["threshold"])
        elif rule.name == PAPER.name:  # an evaluation written before both rules were reported
            keys = [row["key"] for row in evaluation[field]]
            threshold = float(evaluation["operating_delta"])
        else:
            raise DataError(f"{config.evaluation} has no results for the {rule.name} rule")
        k = int(evaluation["k"])
        memory_dir = Path(config.memory or evaluation["memory"])
    except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError) as error:
        raise DataError(
            f"{config.evaluation} is not an evaluation written by `robofailring evaluate` ({error})"
        ) from error
    check_output_folder(config.out, inputs=[config.data, memory_dir])
    with output_lock(config.out):
        remove_file_leftovers(config.out)
        remove_file_leftovers(Path(config.out) / config.kind)
        return _replay_keys(config, keys, rule, threshold, k, memory_dir)


def _replay_keys(
    config: ReviewConfig, keys: list[str], rule: ScoringRule, threshold: float, k: int, memory_dir: Path
) -> ReplayResult:
    result = ReplayResult()
    if not keys:
        return result
    loaded = load_detector(
        memory_dir,
        delta=threshold if rule is PAPER else None,
        gamma=threshold if rule is CONTRAST else None,
        eta=threshold if rule is NOVELTY else None,
        score=rule.name,
        k=k,
        encoder=None,
        cache_dir=config.cache_dir,
        device=config.device,
        data_root=config.data_root,
    )
    dataset = load_dataset(config.data)
    result.skipped_inputs += dataset.skipped
    trajectories = {t.key: t for t in dataset.select(keys=keys)}
    result.references[memory_dir] = loaded.references
    with progress_bar(total=len(keys), desc=f"replaying {config.kind}", unit="trajectory") as bar:
        for key in keys:
            trajectory = trajectories[key]
            trace = loaded.detector.run(trajectory)
            focus = trace.t_det if trace.t_det is not None else int(np.argmax(trace.max_score()))
            out = Path(config.out) / config.kind / recording_name(trajectory)
            check_recording_file(out)
            result.recordings.append(
                record_replay(
                    trajectory,
                    trace,
                    out=out,
                    memory_map=loaded.map,
                    focus_frame=focus,
                    vlm_answer=result.ask(config.vlm, trace, trajectory),
                    camera_codec=config.camera_codec,
                )
            )
            bar.update(1)
    return result
