"""The scores panel: S⁻_t per view against δ and State_t, with the two timelines (frame, time).

A task without failure entries has no S⁻_t: only State_t is logged here (N_t and η are the contrast panel's)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import numpy as np

from rfr_viz.paths import FRAME, TIME, DetectorPaths
from rfr_viz.styles import DELTA_COLOUR, STATE_COLOUR, VIEW_COLOURS
from robofailring.detection.band import Band
from robofailring.detection.detector import DetectionTrace
from robofailring.detection.rules import PAPER, ScoringRule
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr


ROW_BATCH: Final[int] = 256
"""Per-frame rows of a replay sent (or logged) between two flushes: what Rerun holds pending for an entity,
and the backlog a slow sink can build, stay this size however long the episode (bench/bench_hdf5_memory.py)."""


def time_columns(frames: np.ndarray, fps: float) -> list[rr.TimeColumn]:
    """The two timelines of a batch of frames: "frame" (sequence) and "time", t / fps rounded to the
    nanosecond as `rr.set_time` rounds it, so columns and rows logged one at a time share their instants."""
    nanos = np.round(1e9 * (frames.astype(np.float64) / fps)).astype("timedelta64[ns]")
    return [rr.TimeColumn(FRAME, sequence=frames), rr.TimeColumn(TIME, duration=nanos)]


def threshold_label(rule: ScoringRule, threshold: float, band: Band | None) -> str:
    """A threshold's name in a plot legend: `γ = 0.030`, or with a band the line it is on the raw score,
    `γ_t = μ_t + 1.230·σ_t (norm band)`."""
    return f"{rule.symbol} = {threshold:.3f}" if band is None else band.label(rule.symbol, threshold)


def set_frame_time(rec: rr.RecordingStream, t: int, fps: float) -> None:
    rec.set_time(FRAME, sequence=t)
    rec.set_time(TIME, duration=t / fps)


def log_score_styles(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    *,
    views: Sequence[str],
    delta: float,
    rule: ScoringRule = PAPER,
    label: str | None = None,
    failures: bool = True,
) -> None:
    """Static line styles of S⁻_t per view, δ and State_t under `rule` (names, colours, widths);
    S⁻_t and δ only where the task has failure entries (`failures`)."""
    prefix = f"{label} · " if label else ""
    for position, view in enumerate(views if failures else ()):
        rec.log(
            paths.score(view),
            rr.SeriesLines(
                colors=[VIEW_COLOURS[position % len(VIEW_COLOURS)]],
                widths=[2.0],
                names=[f"{prefix}{view} S⁻ (failure)"],
            ),
            static=True,
        )
    if failures:
        rec.log(
            paths.delta,
            rr.SeriesLines(colors=[DELTA_COLOUR], widths=[1.5], names=[f"{prefix}δ = {delta:.3f}"]),
            static=True,
        )
    rec.log(
        paths.state,
        rr.SeriesLines(
            colors=[STATE_COLOUR],
            widths=[1.5],
            names=[f"{prefix}State_t ({rule.name}: any view {rule.score_name} ≥ {rule.symbol})"],
        ),
        static=True,
    )


def log_scores(
    rec: rr.RecordingStream,
    trace: DetectionTrace,
    paths: DetectorPaths,
    fps: float,
    *,
    label: str | None,
) -> None:
    failures = trace.has_failures
    log_score_styles(
        rec,
        paths,
        views=trace.views,
        delta=trace.delta,
        rule=trace.rule,
        label=label,
        failures=failures,
    )
    for view in trace.views if failures else ():
        similarity = np.asarray(trace.similarity[view], dtype=np.float64)
        present = np.flatnonzero(np.isfinite(similarity))
        rec.send_columns(
            paths.score(view),
            indexes=time_columns(present, fps),
            columns=rr.Scalars.columns(scalars=similarity[present]),
        )
    frames = np.arange(trace.length)
    if failures:
        rec.send_columns(
            paths.delta,
            indexes=time_columns(frames, fps),
            columns=rr.Scalars.columns(scalars=trace.threshold_line(PAPER).astype(np.float64)),
        )
    scored = trace.scored_frames  # with a stride, State_t exists only where frames were scored
    rec.send_columns(
        paths.state,
        indexes=time_columns(scored, fps),
        columns=rr.Scalars.columns(scalars=trace.state[scored].astype(np.float64)),
    )
