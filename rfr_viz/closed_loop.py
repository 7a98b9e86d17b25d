"""Closed loop in the simulator: the detector watches the robot live and stops it at the alarm."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from rfr_viz._images import JPEG_MEDIA_TYPE, JPEG_QUALITY
from rfr_viz.blueprint import side_panels
from rfr_viz.panel_scores import set_frame_time, time_columns
from rfr_viz.paths import (
    CLOSED_LOOP_SUMMARY,
    FRAME,
    PROPERTIES,
    UNSTOPPED,
    WATCHED,
    ClosedLoopPaths,
    DetectorPaths,
)
from rfr_viz.record import open_recording
from rfr_viz.styles import DELTA_COLOUR, STATE_COLOUR, VIEW_COLOURS
from robofailring.data.images import encode_jpeg
from robofailring.detector import DEFAULT_K, FailureDetector, StepResult
from robofailring.encoders.base import Encoder
from robofailring.encoders.cache import CachedEncoder
from robofailring.memory import FailureMemory, Neighbor
from robofailring.scoring import ScoreRule
from robofailring.sim import VIEWS, EpisodeResult, GoalCheck, run_episode
from robofailring.sim.episode import episode_fps

STOP_COLOUR: Final[tuple[int, int, int]] = (235, 60, 60)


@dataclass(frozen=True)
class _RunLog:
    """One run of the episode: the detector's steps, the JPEG frames per view and the goal check."""

    steps: list[StepResult]
    jpegs: dict[str, list[bytes]] = field(repr=False)
    size: tuple[int, int]  # width, height of the camera images
    result: EpisodeResult

    @property
    def fired_at(self) -> int | None:
        return next((step.t for step in self.steps if step.state), None)


@dataclass(frozen=True)
class ClosedLoopResult:
    """The recording and what happened: where the watched run stopped, and both goal checks."""

    path: Path
    stop_frame: int | None  # the first alarm (State_t = 1), where the watched run was stopped
    stop_view: str | None  # the view with the highest S_t among those over δ at the stop
    watched: EpisodeResult  # goal check of the scene as the stop left it (the full run if no alarm)
    unstopped: EpisodeResult  # goal check after all L frames
    length: int  # L: frames of the full episode
    delta: float
    watched_steps: list[StepResult] = field(repr=False)
    unstopped_steps: list[StepResult] = field(repr=False)

    @property
    def saving_ratio(self) -> float | None:
        """T_s = 1 − t_det / L (paper Table 2), None without an alarm."""
        return None if self.stop_frame is None else 1.0 - self.stop_frame / self.length


def run_closed_loop(
    *,
    memory: FailureMemory,
    encoder: Encoder | CachedEncoder,
    task: str,
    mode: str,
    seed: int,
    out: Path,
    delta: float | None = None,
    k: int = DEFAULT_K,
    ood: bool = False,
    image_size: int = 128,
    frames: int = 40,
    recording_id: str | None = None,
) -> ClosedLoopResult:
    """Run one simulated episode twice and write both runs side by side into one `.rrd` at `out`.

    The watched run feeds every frame to a detector session and stops the robot at the first alarm;
    the unstopped run is the same episode (same task, mode and seed) scored but never stopped.
    `delta` defaults to the memory's calibrated δ, else the paper's.
    """
    detector = FailureDetector(memory, encoder, delta=delta, k=k, rule=ScoreRule.PAPER)  # S_t ≥ δ, as logged
    watched, unstopped = (
        _run(detector, task, mode, seed, act=act, ood=ood, image_size=image_size, frames=frames)
        for act in (True, False)  # the same episode: stopped at the first alarm, then left to run
    )
    stop = watched.fired_at
    stop_view = None if stop is None else _alarm(watched.steps[stop])[0]
    fps = episode_fps(frames)
    blueprint = closed_loop_blueprint(views=VIEWS, fps=fps, length=frames, focus=stop)
    with open_recording(Path(out), blueprint, recording_id=recording_id) as rec:
        rec.send_recording_name(f"{task}/{mode}/seed {seed} (closed loop)")
        rec.send_property(
            PROPERTIES,
            rr.AnyValues(
                task=task,
                mode=mode,
                seed=seed,
                label=unstopped.result.label or unstopped.result.outcome,
                outcome_watched=watched.result.outcome,
                outcome_unstopped=unstopped.result.outcome,
                encoder=detector.encoder.identity,
                delta=detector.delta,
                k=k,
                t_det=-1 if stop is None else stop,  # -1: no alarm, the watched run was not stopped
                stop_view=stop_view or "",
                L=frames,
                fps=fps,
            ),
        )
        for paths, run in ((WATCHED, watched), (UNSTOPPED, unstopped)):
            _log_run(rec, paths, run, delta=detector.delta, length=frames, fps=fps, stopped=paths is WATCHED)
        summary = _summary(
            task=task, mode=mode, seed=seed, detector=detector, watched=watched, unstopped=unstopped
        )
        rec.log(CLOSED_LOOP_SUMMARY, rr.TextDocument(summary, media_type=rr.MediaType.MARKDOWN), static=True)
    return ClosedLoopResult(
        path=Path(out),
        stop_frame=stop,
        stop_view=stop_view,
        watched=watched.result,
        unstopped=unstopped.result,
        length=frames,
        delta=detector.delta,
        watched_steps=watched.steps,
        unstopped_steps=unstopped.steps,
    )


def _run(
    detector: FailureDetector,
    task: str,
    mode: str,
    seed: int,
    *,
    act: bool,
    ood: bool,
    image_size: int,
    frames: int,
) -> _RunLog:
    """The control loop: every frame goes to the detector; with `act`, the first alarm stops the robot."""
    session = detector.session(task)
    steps: list[StepResult] = []
    jpegs: dict[str, list[bytes]] = {}
    size = (image_size, image_size)
    with run_episode(task, mode, seed, ood=ood, image_size=image_size, frames=frames) as run:
        for images in run:
            step = session.step(images)
            steps.append(step)
            for view, rgb in images.items():
                jpegs.setdefault(view, []).append(encode_jpeg(rgb, quality=JPEG_QUALITY))
                size = (rgb.shape[1], rgb.shape[0])
            if act and step.state:
                run.stop()  # the goal is checked on the scene as the robot leaves it now
        result = run.run_to_end()
    return _RunLog(steps=steps, jpegs=jpegs, size=size, result=result)


def _alarm(step: StepResult) -> tuple[str, Neighbor]:
    """The view that fired with the highest S_t, and its nearest memory entry."""
    view = max(step.fired_views, key=lambda v: step.similarity[v])
    return view, step.neighbors[view][0]


def _goal_values(goal: GoalCheck) -> str:
    """The numbers the goal check decided from, e.g. "lift_m = 0.000" (never "-0.000")."""
    return ", ".join(f"{key} = {round(value, 3) + 0.0:.3f}" for key, value in goal.values.items())


def _outcome_line(name: str, run: _RunLog, length: int) -> str:
    values = _goal_values(run.result.goal)
    label = f" ({run.result.label})" if run.result.label else ""
    return (
        f"{name} run ended after {run.result.frames}/{length} frames: goal check "
        f"{run.result.outcome.upper()}{label}; {values}"
    )


def _log_run(
    rec: rr.RecordingStream,
    paths: ClosedLoopPaths,
    run: _RunLog,
    *,
    delta: float,
    length: int,
    fps: float,
    stopped: bool,
) -> None:
    """Cameras, S_t, δ, State_t and the alarm event of one run; the watched cameras end at the stop."""
    rendered = len(run.steps)
    frames = np.arange(rendered)
    for position, view in enumerate(run.jpegs):
        blobs = run.jpegs[view]
        rec.send_columns(
            paths.camera(view),
            indexes=time_columns(frames, fps),
            columns=rr.EncodedImage.columns(blob=blobs, media_type=[JPEG_MEDIA_TYPE] * len(blobs)),
        )
        rec.log(
            paths.detector.score(view),
            rr.SeriesLines(colors=[VIEW_COLOURS[position % len(VIEW_COLOURS)]], widths=[2.0], names=[view]),
            static=True,
        )
        rec.send_columns(
            paths.detector.score(view),
            indexes=time_columns(frames, fps),
            columns=rr.Scalars.columns(scalars=[step.similarity[view] for step in run.steps]),
        )
    rec.log(
        paths.detector.delta,
        rr.SeriesLines(colors=[DELTA_COLOUR], widths=[1.0], names=[f"δ = {delta:.3f}"]),
        static=True,
    )
    rec.send_columns(
        paths.detector.delta,
        indexes=time_columns(frames, fps),
        columns=rr.Scalars.columns(scalars=np.full(rendered, delta)),
    )
    rec.log(
        paths.detector.state,
        rr.SeriesLines(colors=[STATE_COLOUR], widths=[1.5], names=["State_t (any view ≥ δ)"]),
        static=True,
    )
    rec.send_columns(
        paths.detector.state,
        indexes=time_columns(frames, fps),
        columns=rr.Scalars.columns(scalars=[float(step.state) for step in run.steps]),
    )
    fired = run.fired_at
    if fired is not None:
        view, top = _alarm(run.steps[fired])
        similarity = run.steps[fired].similarity[view]
        what = f"STOP issued at frame {fired}" if stopped else f"alarm at frame {fired}, not acted on"
        set_frame_time(rec, fired, fps)
        rec.log(
            paths.detector.event,
            rr.TextLog(
                f"{paths.run}: {what}: view {view}, S_t = {similarity:.3f} ≥ δ = {delta:.3f}; nearest memory entry "
                f"{top.entry.episode} [{top.entry.view}] {top.entry.symbol}: {top.entry.description}",
                level=rr.TextLogLevel.WARN,
            ),
        )
        if stopped:
            for camera_view in run.jpegs:
                _log_stopped(rec, paths.stopped(camera_view), run.size, f"STOPPED at frame {fired}")
    set_frame_time(rec, rendered - 1, fps)
    rec.log(
        paths.outcome,
        rr.TextLog(
            _outcome_line(paths.run, run, length),
            level=rr.TextLogLevel.INFO if run.result.goal.passed else rr.TextLogLevel.ERROR,
        ),
    )


def _log_stopped(rec: rr.RecordingStream, entity: str, size: tuple[int, int], label: str) -> None:
    """A red frame around the frozen camera image, with the label near its top."""
    width, height = size
    rec.log(
        entity,
        rr.Boxes2D(
            mins=[[1.0, 1.0]],
            sizes=[[width - 2.0, height - 2.0]],
            colors=[STOP_COLOUR],
            radii=rr.Radius.ui_points(2.5),
        ),
        rr.Points2D(
            [[width / 2, 0.12 * height]],
            colors=[(255, 255, 255)],
            radii=rr.Radius.ui_points(0.0),
            labels=[label],
            show_labels=True,
        ),
    )


def _summary(
    *, task: str, mode: str, seed: int, detector: FailureDetector, watched: _RunLog, unstopped: _RunLog
) -> str:
    """Markdown: both runs' goal checks side by side, then what the detector retrieved at the stop."""
    length = len(unstopped.steps)
    lines = [
        f"**{task} · {mode} · seed {seed}** · `{detector.encoder.identity}` · δ = {detector.delta:.3f} · "
        f"K = {detector.k} · L = {length}",
        "",
    ]
    lines += ["| run | frames | goal check | label |", "|---|---|---|---|"]
    for name, run in (("watched", watched), ("unstopped", unstopped)):
        values = _goal_values(run.result.goal)
        lines.append(
            f"| {name} | {run.result.frames}/{length}{' (stopped)' if run.result.stopped_early else ''} | "
            f"**{run.result.outcome}** ({values}) | {run.result.label or '—'} |"
        )
    lines.append("")
    stop = watched.fired_at
    if stop is None:
        peak = max(max(step.similarity.values()) for step in unstopped.steps)
        lines.append(f"**No alarm**: the highest S_t is {peak:.3f} < δ, so the robot was never stopped.")
    else:
        view, top = _alarm(watched.steps[stop])
        lines.append(
            f"**STOP at frame {stop}** (T_s = {1 - stop / length:.2f}), view {view}, "
            f"S_t = {watched.steps[stop].similarity[view]:.3f}; nearest: {top.entry.symbol} "
            f"({top.entry.episode}, {top.entry.view}): *{top.entry.description}*"
        )
    return "\n".join(lines)


def _score_plot(paths: DetectorPaths, *, name: str, length: int) -> rrb.Container:
    """S_t of every view with δ; State_t in a thin plot below; both span all L frames of the episode."""
    frames = rrb.TimeAxis(
        view_range=rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seq=0),
            end=rrb.TimeRangeBoundary.absolute(seq=length - 1),
        )
    )
    scores = rrb.TimeSeriesView(
        origin="/",
        contents=[f"{paths.score_root}/**"],
        name=name,
        axis_x=frames,
        plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.LeftBottom, visible=True),
    )
    state = rrb.TimeSeriesView(
        origin="/",
        contents=[paths.state],
        name="State_t (any view ≥ δ)",
        axis_x=frames,
        titlebar=False,  # its legend names it: the plot keeps its few pixels for the 0/1 line
        axis_y=rrb.ScalarAxis(range=(-0.1, 1.1), zoom_lock=True),
        plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.LeftTop, visible=True),
    )
    return rrb.Vertical(scores, state, row_shares=[3, 1.1])


def closed_loop_blueprint(
    *, views: Sequence[str], fps: float, length: int, focus: int | None = None
) -> rrb.Blueprint:
    """One row per run (cameras | S_t and State_t), the events and the outcome table below."""
    rows = []
    for paths, title in ((WATCHED, "watched (stopped at the alarm)"), (UNSTOPPED, "unstopped")):
        cameras = rrb.Horizontal(
            *(rrb.Spatial2DView(origin=paths.camera(view), name=f"{paths.run} · {view}") for view in views)
        )
        plot = _score_plot(paths.detector, name=f"{title} · S_t per view and δ", length=length)
        rows.append(rrb.Horizontal(cameras, plot, column_shares=[len(views), 2.0]))
    events = rrb.TextLogView(
        origin="/",
        contents=[f"{paths.root}/**" for paths in (WATCHED, UNSTOPPED)],
        name="events (the alarm, the stop, each run's goal check)",
        columns=rrb.TextLogColumns(
            timeline_columns=[rrb.encodings.TimelineColumn(FRAME)],
            text_log_columns=[
                rrb.encodings.TextLogColumn("LogLevel"),
                rrb.encodings.TextLogColumn("Body"),
                rrb.encodings.TextLogColumn("EntityPath", visible=False),
            ],
        ),
    )
    summary = rrb.TextDocumentView(origin=CLOSED_LOOP_SUMMARY, name="outcome of both runs")
    text = rrb.Horizontal(events, summary, column_shares=[1, 1.1])
    return rrb.Blueprint(rrb.Vertical(*rows, text, row_shares=[1, 1, 0.85]), *side_panels(fps, focus))
