"""False-positive (and miss) review: replay only the false alarms or the misses of an evaluation."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Final

import numpy as np

from rfr_viz.codecs import CameraCodec
from rfr_viz.jobs.replay import ReplayResult, load_detector, recording_name
from rfr_viz.panels.map import placer
from rfr_viz.paths import DEFAULT_OUT
from rfr_viz.recordings.replay import record_replay
from rfr_viz.viewer.rrd import check_recording_file
from robofailring.atomic import output_lock, remove_file_leftovers, write_text_atomic
from robofailring.data.labels import merge_label_rows
from robofailring.data.model import Skipped
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_DETECTOR, DetectorConfig
from robofailring.detection.loader import detector_from
from robofailring.detection.rules import PAPER, ScoringRule, reported_default, rule_named
from robofailring.detection.trace import DetectionTrace
from robofailring.errors import DataError, OutputError
from robofailring.explain.vlm import VLMConfig
from robofailring.jsontext import parse_json
from robofailring.outputs import check_not_input, check_output_folder, check_writable
from robofailring.progress import progress_bar

KINDS: Final[tuple[str, ...]] = ("false-alarms", "misses")


@dataclass(frozen=True)
class ReviewConfig:
    evaluation: Path  # the <name>.json written by `robofailring evaluate`
    data: DataSelection  # the dataset that evaluation tested on, how it is read
    kind: str = "false-alarms"  # "false-alarms" (successes that fired) or "misses" (failures that did not)
    out: Path = DEFAULT_OUT / "review"
    # its memory (default: the one the evaluation used), device, cache and data root, and its rule: the one
    # whose alarms to review (default: contrast when evaluated, else paper); the threshold and K are the
    # evaluation's
    detector: DetectorConfig = DEFAULT_DETECTOR
    vlm: VLMConfig | None = None  # ask this VLM about each alarm; its answer joins the report
    camera_codec: CameraCodec = CameraCodec.AUTO  # jpeg, av1, h264, or auto (by size)
    write_labels: Path | None = None  # `write_review_labels`: the labels CSV of every false alarm and miss


@dataclass(frozen=True)
class Reviewed:
    """What an evaluation says to review: its rule, threshold, K, memory, and keys per kind."""

    rule: ScoringRule
    threshold: float
    k: int
    memory_dir: Path
    keys: dict[str, list[str]]  # per kind (KINDS): the trajectory keys


def review(config: ReviewConfig) -> ReplayResult:
    """One recording per false alarm (focused on the alarm) or per miss (focused on its peak S_t).

    `write_review_labels` writes a labels file of both kinds instead.
    """
    if config.kind not in KINDS:
        raise DataError(f"review kind {config.kind!r} is not one of {list(KINDS)}")
    reviewed = _read_evaluation(config)
    check_output_folder(config.out, inputs=[config.data.root, reviewed.memory_dir])
    with output_lock(config.out):
        remove_file_leftovers(config.out)
        remove_file_leftovers(Path(config.out) / config.kind)
        return _replay_keys(
            config,
            reviewed.keys[config.kind],
            reviewed.rule,
            reviewed.threshold,
            reviewed.k,
            reviewed.memory_dir,
        )


def _read_evaluation(config: ReviewConfig) -> Reviewed:
    try:
        evaluation = parse_json(
            Path(config.evaluation).read_bytes(), source=f"evaluation {config.evaluation}"
        )
        rules = evaluation.get("rules") or {}
        rule = rule_named(config.detector.rule) if config.detector.rule else reported_default(rules)
        if rule.name in rules:
            keys = {kind: list(rules[rule.name][kind.replace("-", "_")]) for kind in KINDS}
            threshold = float(rules[rule.name]["threshold"])
        elif rule.name == PAPER.name:  # an evaluation written before both rules were reported
            keys = {kind: [row["key"] for row in evaluation[kind.replace("-", "_")]] for kind in KINDS}
            threshold = float(evaluation["operating_delta"])
        else:
            raise DataError(f"{config.evaluation} has no results for the {rule.name} rule")
        k = int(evaluation["k"])
        memory_dir = Path(config.detector.memory or evaluation["memory"])
    except (OSError, AttributeError, KeyError, TypeError, ValueError) as error:
        raise DataError(
            f"{config.evaluation} is not an evaluation written by `robofailring evaluate` ({error})"
        ) from error
    return Reviewed(rule=rule, threshold=threshold, k=k, memory_dir=memory_dir, keys=keys)


def _replay_keys(
    config: ReviewConfig, keys: list[str], rule: ScoringRule, threshold: float, k: int, memory_dir: Path
) -> ReplayResult:
    result = ReplayResult()
    if not keys:
        return result
    loaded = load_detector(
        config.detector.with_memory(
            memory_dir,
            thresholds={rule.name: threshold},
            rule=rule.name,
            scoring=replace(config.detector.scoring, k=k),
        ),
        config.data.root,
    )
    dataset = config.data.load(keys=keys)
    result.skipped_inputs += dataset.skipped
    trajectories = {t.key: t for t in dataset.trajectories()}
    result.references[memory_dir] = loaded.references
    with progress_bar(total=len(keys), desc=f"replaying {config.kind}", unit="trajectory") as bar:
        for key in keys:
            trajectory = trajectories[key]
            trace = loaded.detector.run(
                trajectory, keep_queries=False, place=placer(loaded.map, trajectory.task)
            )
            result.skipped_inputs += trace.short_views
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


#: The columns of `review --write-labels`: what the detector said, then `outcome`, `symbol` and
#: `description` left empty for a person to fill (`robofailring.data.labels` reads them back).
LABEL_COLUMNS: Final[tuple[str, ...]] = (
    "episode",
    "task",
    "review",
    "detected",
    "suggested_symbol",
    "frame",
    "view",
    "score",
    "rule",
    "outcome",
    "symbol",
    "description",
)


@dataclass(frozen=True)
class ReviewLabels:
    """The labels file `review --write-labels` wrote: its path, its rows, what the data loader did not read."""

    path: Path
    rows: list[dict[str, str]]  # this review's rows (its false alarms and misses)
    skipped_inputs: list[Skipped]
    unlabelled: int = 0  # rows of the file written still without an outcome: what is left to label
    total: int = 0  # rows of the file written, other episodes' included


def write_review_labels(config: ReviewConfig) -> ReviewLabels:
    """A labels CSV with one row per false alarm and per miss of the evaluation, written atomically.

    Each row: the episode, what the detector said (`detected`), the nearest failure's symbol at the
    alarm (a miss: at its peak score) as `suggested_symbol`, that frame, view and score, and empty
    `outcome`, `symbol` and `description` columns to fill; `--labels` reads the file back (rows
    still without an outcome are reported as not applied). Into an existing labels CSV the rows are
    merged (`robofailring.data.labels.merge_label_rows`): what a person filled in is kept, other
    episodes' rows stay, and a file that is not a labels CSV is refused before any work.
    """
    if config.write_labels is None:
        raise DataError("write_review_labels needs a labels file to write (--write-labels FILE)")
    reviewed = _read_evaluation(config)
    path = Path(config.write_labels)
    inputs = [config.data.root, reviewed.memory_dir, config.evaluation]
    check_not_input(path, inputs, replaces=False, flag="--write-labels")
    if path.is_dir():
        raise OutputError(f"--write-labels {path} is a folder; name a CSV file, e.g. labels.csv")
    check_writable(path.absolute().parent)
    with output_lock(path):
        merge_label_rows(path, [], LABEL_COLUMNS)  # refuse a file that is not a labels CSV before any work
        detector = detector_from(
            config.detector.with_memory(
                reviewed.memory_dir,
                thresholds={reviewed.rule.name: reviewed.threshold},
                rule=reviewed.rule.name,
                scoring=replace(config.detector.scoring, k=reviewed.k),
            ),
            trusted=[config.data.root],
        )
        dataset = config.data.load(vocabulary=detector.memory.vocabulary)
        wanted = [key for kind in KINDS for key in reviewed.keys[kind]]
        trajectories = {t.key: t for t in dataset.select(keys=wanted)}
        rows = []
        with progress_bar(total=len(wanted), desc="reviewing", unit="trajectory") as bar:
            for kind in KINDS:
                for key in reviewed.keys[kind]:
                    rows.append(_label_row(detector.run(trajectories[key], keep_queries=False), kind=kind))
                    bar.update(1)
        columns, merged = merge_label_rows(path, rows, LABEL_COLUMNS)  # what a person filled in stays
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(merged)
        write_text_atomic(path, buffer.getvalue(), claim=True)
    unlabelled = sum(not row.get("outcome", "").strip() for row in merged)
    return ReviewLabels(
        path=path, rows=rows, skipped_inputs=list(dataset.skipped), unlabelled=unlabelled, total=len(merged)
    )


def _label_row(trace: DetectionTrace, *, kind: str) -> dict[str, str]:
    """One labels row: the evaluation's outcome for a trajectory and the detector's view of it at its
    alarm (a run that does not fire now: at its peak score)."""
    focus = trace.t_det if trace.t_det is not None else int(np.nanargmax(trace.max_score()))
    scores = trace.all_scores_of(trace.rule)
    view = trace.camera_at(trace.detected_view, focus) or max(
        trace.views, key=lambda v: float(np.nan_to_num(scores[v][focus], nan=-np.inf))
    )
    nearest = trace.neighbors(view, focus)
    return {
        "episode": trace.episode,
        "task": trace.task,
        "review": "false alarm" if kind == "false-alarms" else "miss",
        "detected": "failure" if kind == "false-alarms" else "success",  # as the evaluation found it
        "suggested_symbol": nearest[0].entry.symbol if nearest else "",
        "frame": str(focus),
        "view": view,
        "score": f"{float(scores[view][focus]):.6f}",
        "rule": trace.rule.name,
        "outcome": "",
        "symbol": "",
        "description": "",
    }
