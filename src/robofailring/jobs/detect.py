"""The detect job: one trajectory replayed through a memory's detector, its report, and the VLM's answer."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from robofailring.data.model import Trajectory
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_STRIDE, DetectorConfig, check_stride
from robofailring.detection.detector import DetectionTrace
from robofailring.detection.loader import detector_from
from robofailring.detection.signal_scores import cameras_alone_note
from robofailring.detection.trace import self_match_warning
from robofailring.explain.report import FailureReport, report_for, signals_sentence
from robofailring.memory.references import ReferenceCheck, check_references

_log = logging.getLogger("robofailring")

if TYPE_CHECKING:
    from robofailring.explain.vlm import VLMAnswer, VLMConfig  # httpx: loaded only when a VLM is asked


@dataclass(frozen=True)
class DetectConfig:
    data: DataSelection  # one episode folder (or a dataset root and `key`), how it is read
    detector: DetectorConfig  # the memory and how its detector judges
    key: str | None = None  # the trajectory to run when `data.root` is a dataset root (`episode_3`)
    leave_one_out: bool = False  # hide the trajectory's own episode from the memory
    stride: int = DEFAULT_STRIDE  # score every stride-th frame (I_0 stays frame 0; t_det in original frames)
    vlm: VLMConfig | None = None  # ask this VLM about the report, when the detector fires

    def __post_init__(self) -> None:  # a bad setting fails before the memory is read
        check_stride(self.stride)


def detect(config: DetectConfig) -> DetectionTrace:
    """Run the detector over one trajectory folder."""
    return detect_trajectory(config)[0]


def detect_trajectory(config: DetectConfig) -> tuple[DetectionTrace, Trajectory]:
    """`detect`, also returning the trajectory it loaded (for the report's current frame)."""
    detector = detector_from(config.detector, trusted=[config.data.root])
    for note in detector.uncalibrated:
        _log.warning("warning: %s", note)
    trajectory = config.data.load_trajectory(key=config.key, vocabulary=detector.memory.vocabulary)
    return detector.run(
        trajectory, leave_one_out=config.leave_one_out, stride=config.stride, keep_queries=False
    ), trajectory


@dataclass(frozen=True)
class DetectResult:
    """What `robofailring detect` found: the trace, its report, the VLM's answer, and what to warn about."""

    trace: DetectionTrace
    report: FailureReport | None  # None: nothing detected
    vlm: VLMConfig | None  # the VLM asked, if any
    answer: VLMAnswer | None  # None: no VLM, or nothing detected to ask about
    references: ReferenceCheck | None  # the fired neighbours' reference images (None: nothing fired)
    layout: str | None = None  # the layout the trajectory was read from
    views_read: tuple[str, ...] = ()  # its views (after `--views`)
    # its frame rate (the layout's, a video's own; None: unknown), for t_det in seconds
    fps: float | None = None

    @property
    def notes(self) -> list[str]:
        """Warnings and notes for stderr: a self-match, a failed VLM call, frames left unscored."""
        trace, notes = self.trace, []
        if trace.in_memory:
            notes.append(self_match_warning([f"{trace.task}/{trace.episode}"]))
        if trace.cameras_alone:
            notes.append(cameras_alone_note([f"{trace.task}/{trace.episode}"]))
        if self.answer is not None and self.answer.error is not None:
            notes.append(f"warning: the VLM call failed: {self.answer.error}")
        for view, count in trace.truncated_views.items():
            notes.append(
                f"note: view {view} has {trace.length + count} frames; the last {count} are not scored "
                f"(views are scored in step up to the shortest one, L = {trace.length})"
            )
        return notes  # views skipped for fewer than 2 frames: listed with what was not read

    def to_dict(self) -> dict[str, Any]:
        """The full trace, the report (None without a detection) and, when a VLM was given, its answer."""
        found = {
            **self.trace.to_dict(),
            "report": self.report.to_dict() if self.report is not None else None,
            "layout": self.layout,
            "views_read": list(self.views_read),
            "fps": self.fps,
            "t_det_s": self.trace.t_det / self.fps if self.fps and self.trace.t_det is not None else None,
        }
        if self.vlm is not None:
            found["vlm"] = self.answer.to_dict() if self.answer is not None else None  # None: nothing to ask
        return found

    def to_json(self) -> str:
        return json.dumps(self.to_dict())

    def to_text(self) -> str:
        """The summary: the rule and threshold, each view's peak scores, and the detection (or none)."""
        trace, rule = self.trace, self.trace.rule
        scored = f", one frame in {trace.stride} scored" if trace.stride > 1 else ""
        band = trace.band
        judged = (
            f"{rule.symbol} = {trace.threshold:.3f}"
            if band is None
            else f"{band.label(rule.symbol, trace.threshold)}, fitted on {band.runs} calibration runs"
        )
        lines = [
            f"task {trace.task}, L = {trace.length} frames{scored}, rule {rule.name}: {rule.score_name} ≥ "
            f"{judged}, K = {trace.k}"
        ]
        shown = {rule.score_name: trace.scores_of(rule) for rule in trace.shown_rules}
        for view in trace.scored_views:
            parts = [
                f"max {name} = {float(np.nanmax(scores[view])):.3f}"
                if np.isfinite(scores[view]).any()
                else f"{name} not scored"
                for name, scores in shown.items()
            ]
            lines.append(f"  {view:>10}: " + ", ".join(parts))
        lines.append(trace.verdict())
        if trace.t_det is None or trace.detected_view is None:
            return "\n".join(lines)
        signals = signals_sentence(trace.signals, trace.t_det)
        if signals is not None:
            lines.append(f"robot signals: {signals}")
        fired_view = trace.camera_at(trace.detected_view, trace.t_det) or trace.detected_view
        found = trace.neighbors(fired_view, trace.t_det)
        if found:
            top = found[0]
            said = (
                f"nearest memory entry {top.entry.task}/{top.entry.episode} [{top.entry.view}] {top.entry.symbol} "
                f"(S⁻_t = {top.similarity:.3f}): {top.entry.description}"
            )
        else:
            said = "no failure of this task in the memory to compare with"
        match = trace.nearest_success(fired_view, trace.t_det)
        if match is not None:
            said += f"; nearest success frame {match.run.episode} frame {match.frame} (S⁺_t = {match.similarity:.3f})"
        lines.append(said)
        if self.answer is not None and self.answer.answer is not None:
            lines.append(f"\nVLM ({self.answer.model}, {self.answer.latency_s:.1f} s):\n{self.answer.answer}")
        return "\n".join(lines)


def run_detect(config: DetectConfig) -> DetectResult:
    """`robofailring detect`: the trace, the failure report when it fires, and the VLM's answer about it."""
    trace, loaded = detect_trajectory(config)
    references = None
    camera = trace.camera_at(trace.detected_view, trace.t_det) if trace.t_det is not None else None
    if trace.t_det is not None and camera is not None:
        neighbors = trace.neighbors(camera, trace.t_det)
        references = check_references(ref for n in neighbors for ref in (n.entry.start, n.entry.end))
    report = report_for(trace, loaded)
    answer = None  # no VLM, or nothing detected to ask about
    if config.vlm is not None and report is not None:
        from robofailring.explain.vlm import ask_vlm

        answer = ask_vlm(report, config.vlm)
    return DetectResult(
        trace=trace,
        report=report,
        vlm=config.vlm,
        answer=answer,
        references=references,
        layout=loaded.layout,
        views_read=tuple(loaded.views),
        fps=loaded.frame_rate,
    )
