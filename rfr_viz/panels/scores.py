"""The scores panel: each shown rule's score per view against its threshold, S⁺_t, and State_t, with the two
timelines (frame, time).

The rules shown are the trace's (`DetectionTrace.shown_rules`): a task without failure entries has no S⁻_t,
a memory without success runs no S⁺_t, and a rule registered beside the built-in ones is plotted as they are."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Final

import numpy as np

from rfr_viz.paths import FRAME, TIME, DetectorPaths
from rfr_viz.styles import STATE_COLOUR, VIEW_COLOURS, threshold_colour
from robofailring.detection.band import Band
from robofailring.detection.detector import DetectionTrace
from robofailring.detection.rules import RULES, RuleThresholds, ScoringRule
from robofailring.extras import needs_extra
from robofailring.memory.signals.modality import SIGNALS_VIEW

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


def threshold_properties(held: RuleThresholds) -> dict[str, float]:
    """Every registered rule's threshold as a recording property, under its option's name (`delta`, `gamma`,
    `eta`, …): what a replay, a comparison and a live recording each say they were judged at."""
    return {rule.threshold_key: float(held.threshold_of(rule)) for rule in RULES.values()}


def set_frame_time(rec: rr.RecordingStream, t: int, fps: float) -> None:
    rec.set_time(FRAME, sequence=t)
    rec.set_time(TIME, duration=t / fps)


def faded(colour: tuple[int, int, int]) -> tuple[int, int, int]:
    """A view's colour, paler: its S⁺_t line beside its scores."""
    return (colour[0] // 2 + 60, colour[1] // 2 + 60, colour[2] // 2 + 60)


def log_score_styles(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    *,
    views: Sequence[str],
    rules: Sequence[ScoringRule],
    judging: ScoringRule,
    thresholds: Mapping[str, float],
    bands: Mapping[str, Band] | None = None,
    successes: bool = False,
    label: str | None = None,
) -> None:
    """Static line styles (names, colours, widths) of each of `rules`' scores per view and its threshold (named
    as the line over time its band makes of it, if any), of S⁺_t per view (`successes`), and of State_t under
    the `judging` rule; the judging rule's lines are the bold ones."""
    prefix = f"{label} · " if label else ""
    bands = bands or {}
    for rule in rules:
        width = 2.0 if rule.name == judging.name else 1.5
        for position, view in enumerate(views):
            rec.log(
                paths.score(view, rule.name),
                rr.SeriesLines(
                    colors=[VIEW_COLOURS[position % len(VIEW_COLOURS)]],
                    widths=[width],
                    names=[f"{prefix}{view} {rule.formula}"],
                ),
                static=True,
            )
        band = bands.get(rule.name)
        rec.log(
            paths.threshold(rule.name),
            rr.SeriesLines(
                colors=[threshold_colour(rule.name)],
                widths=[1.5 if rule.name == judging.name else 1.0],
                names=[prefix + threshold_label(rule, thresholds[rule.name], band)],
            ),
            static=True,
        )
        for position, view in enumerate(views):
            if band is not None and view in band.views:  # judged by its own band: its own line, its colour
                rec.log(
                    paths.view_threshold(rule.name, view),
                    rr.SeriesLines(
                        colors=[faded(VIEW_COLOURS[position % len(VIEW_COLOURS)])],
                        widths=[1.5 if rule.name == judging.name else 1.0],
                        names=[
                            f"{prefix}{view} {threshold_label(rule, thresholds[rule.name], band.of(view))}"
                        ],
                    ),
                    static=True,
                )
    for position, view in enumerate(views if successes else ()):
        rec.log(
            paths.success_score(view),
            rr.SeriesLines(
                colors=[faded(VIEW_COLOURS[position % len(VIEW_COLOURS)])],
                widths=[1.0],
                names=[f"{prefix}{view} S⁺ (success)"],
            ),
            static=True,
        )
    rec.log(
        paths.state,
        rr.SeriesLines(
            colors=[STATE_COLOUR],
            widths=[1.5],
            names=[f"{prefix}State_t ({judging.name}: any view {judging.score_name} ≥ {judging.symbol})"],
        ),
        static=True,
    )


def send_series(rec: rr.RecordingStream, path: str, values: np.ndarray, *, fps: float) -> None:
    """One scalar series as columns, at the frames where it is finite (NaN: not scored)."""
    values = np.asarray(values, dtype=np.float64)
    present = np.flatnonzero(np.isfinite(values))
    rec.send_columns(
        path, indexes=time_columns(present, fps), columns=rr.Scalars.columns(scalars=values[present])
    )


def log_scores(
    rec: rr.RecordingStream,
    trace: DetectionTrace,
    paths: DetectorPaths,
    fps: float,
    *,
    label: str | None,
) -> None:
    """`/score/<view>/<rule>` and `/score/threshold/<rule>` for each rule the trace shows (and
    `/score/threshold/<rule>/<view>` for a view judged by a band of its own), `/score/<view>/success` (S⁺_t,
    when the memory has success runs) and `/detection/state`."""
    rules = trace.shown_rules
    successes = bool(trace.success_similarity)
    log_score_styles(
        rec,
        paths,
        views=trace.scored_views,
        rules=rules,
        judging=trace.rule,
        thresholds={rule.name: trace.threshold_of(rule) for rule in rules},
        bands=trace.bands,
        successes=successes,
        label=label,
    )
    for rule in rules:
        scores = trace.scores_of(rule)
        for view in trace.scored_views:
            send_series(rec, paths.score(view, rule.name), scores[view], fps=fps)
        send_series(rec, paths.threshold(rule.name), trace.threshold_line(rule), fps=fps)
        own = trace.bands[rule.name].views if rule.name in trace.bands else {}
        for view in trace.scored_views:
            if view in own:  # e.g. the signals under per-modality: not the cameras' line
                send_series(
                    rec, paths.view_threshold(rule.name, view), trace.threshold_line(rule, view), fps=fps
                )
    for view in trace.views if successes else ():
        send_series(rec, paths.success_score(view), trace.success_similarity[view], fps=fps)
    if successes and trace.signals is not None:
        send_series(rec, paths.success_score(SIGNALS_VIEW), trace.signals.success_similarity, fps=fps)
    scored = trace.scored_frames  # with a stride, State_t exists only where frames were scored
    rec.send_columns(
        paths.state,
        indexes=time_columns(scored, fps),
        columns=rr.Scalars.columns(scalars=trace.state[scored].astype(np.float64)),
    )
