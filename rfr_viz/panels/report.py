"""The report panel: the detection event and the failure report (eq. 8, Appendix B) at t_det."""

from __future__ import annotations

import re

import numpy as np

from rfr_viz.panels.scores import set_frame_time, threshold_label
from rfr_viz.paths import DetectorPaths
from robofailring.data.model import Trajectory
from robofailring.detection.detector import DetectionTrace
from robofailring.detection.rules import ScoringRule
from robofailring.explain.report import FailureReport, report_for
from robofailring.explain.vlm import VLMAnswer
from robofailring.extras import needs_extra
from robofailring.memory.failure import Neighbor
from robofailring.memory.success import SuccessMatch

with needs_extra("viz"):
    import rerun as rr

_MARKDOWN_IMAGE = re.compile(r"!\[([^\]]*)\]\(([^)]*)\)")


def _markdown_without_images(markdown: str) -> str:
    """Image links become plain references: the viewer must not try to fetch local files."""
    return _MARKDOWN_IMAGE.sub(lambda match: f"`{match[1] or 'image'}: {match[2]}`", markdown)


def log_detection(
    rec: rr.RecordingStream,
    trace: DetectionTrace,
    paths: DetectorPaths,
    fps: float,
    trajectory: Trajectory | None,
    vlm_answer: VLMAnswer | None = None,
) -> None:
    """The detection event and the failure report at t_det (and the VLM's answer); a summary at frame 0."""
    t_det, view = trace.t_det, trace.detected_view
    rule = trace.rule
    peak = trace.max_score()  # judged (band-corrected), so its highest frame is the nearest miss
    peak_frame = int(np.argmax(peak))
    line = trace.threshold_line()
    summary = (
        f"**{trace.task} · {trace.episode}** — encoder `{trace.encoder}`, rule **{rule.name}** "
        f"({rule.score_name} ≥ {threshold_label(rule, trace.threshold, trace.band)}), K = {trace.k}, "
        f"L = {trace.length} frames.\n\n"
    )
    set_frame_time(rec, 0, fps)
    symbol = rule.symbol if rule.name not in trace.bands else f"{rule.symbol}_t"  # a band's line at that t
    if t_det is None or view is None:
        rec.log(
            paths.report,
            rr.TextDocument(
                summary + f"**No failure detected.** {rule.score_name} came nearest its threshold at frame "
                f"{peak_frame}: {float(trace.raw_max_score(rule)[peak_frame]):.3f} (highest over all views), "
                f"below {symbol} = {float(line[peak_frame]):.3f} there.",
                media_type=rr.MediaType.MARKDOWN,
            ),
        )
        return
    rec.log(
        paths.report,
        rr.TextDocument(
            summary + f"No failure yet: the {rule.name} rule fires at frame **{t_det}** (view {view}).",
            media_type=rr.MediaType.MARKDOWN,
        ),
    )
    report = report_for(trace, trajectory)
    assert report is not None  # t_det is set
    camera = trace.camera_at(view, t_det)  # the firing camera, or the highest when the signals fired
    neighbors = trace.neighbors(camera, t_det) if camera is not None else []
    set_frame_time(rec, t_det, fps)
    fired = (
        f"{rule.score_name} = {float(trace.scores[view][t_det]):.3f} ≥ {symbol} = {float(line[t_det]):.3f}"
    )
    success = trace.nearest_success(camera, t_det) if camera is not None else None
    contrast_line = ""
    if success is not None and neighbors:
        contrast_line = (
            f"Contrast: S⁻ = {neighbors[0].similarity:.3f} (nearest failure: {neighbors[0].entry.episode}, "
            f"{neighbors[0].entry.moment}) − S⁺ = {success.similarity:.3f} "
            f"(nearest success frame: {success.run.episode}, frame {success.frame}) = "
            f"C = {neighbors[0].similarity - success.similarity:.3f}.\n\n"
        )
    elif success is not None:
        contrast_line = (
            f"Novelty: N = 1 − S⁺ = {1 - success.similarity:.3f} (nearest success frame: "
            f"{success.run.episode}, frame {success.frame}); no failure of this task in the memory.\n\n"
        )
    log_alarm(
        rec,
        paths,
        report=report,
        top=neighbors[0] if neighbors else None,
        nearest_success=success,
        rule=rule,
        fired=fired,
        summary=summary
        + f"**Fired by the {rule.name} rule** at frame {t_det}, view {view}: {fired}.\n\n"
        + (f"Robot signals: {report.signals}.\n\n" if report.signals is not None else "")
        + (f"Camera {camera}: " if camera != view and contrast_line else "")
        + contrast_line,
        vlm_answer=vlm_answer,
    )


def log_alarm(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    *,
    report: FailureReport,
    top: Neighbor | None,
    rule: ScoringRule,
    fired: str,
    summary: str,
    vlm_answer: VLMAnswer | None = None,
    nearest_success: SuccessMatch | None = None,
) -> None:
    """At the detection instant (the current time): the event line and the failure report document.

    `fired` says on what score `rule` fired (e.g. "S⁻_t = 0.970 ≥ δ = 0.950"); without a failure
    neighbour the event names the robot's signals' nearest runs (they fired with no camera beside them), else
    the nearest success frame (`top` None: a task of success runs only)."""
    if top is not None:
        nearest = (
            f"nearest memory entry {top.entry.task}/{top.entry.episode} [{top.entry.view}] "
            f"{top.entry.symbol}: {top.entry.description}"
        )
    elif report.signals is not None and not report.items:  # the signals judged alone: their nearest runs
        nearest = f"robot signals: {report.signals}"
    else:
        nearest = "no failure of this task in the memory" + (
            f"; nearest success frame {nearest_success.run.episode} frame {nearest_success.frame} "
            f"(S⁺ = {nearest_success.similarity:.3f})"
            if nearest_success is not None
            else ""
        )
    rec.log(
        paths.event,
        rr.TextLog(
            f"FAILURE at frame {report.t_det} in view {report.view} ({rule.name} rule): {fired}; {nearest}",
            level=rr.TextLogLevel.WARN,
        ),
    )
    rec.log(
        paths.report,
        rr.TextDocument(
            summary
            + (vlm_answer.to_markdown() + "\n\n" if vlm_answer is not None else "")
            + _markdown_without_images(report.to_markdown()),
            media_type=rr.MediaType.MARKDOWN,
        ),
    )
