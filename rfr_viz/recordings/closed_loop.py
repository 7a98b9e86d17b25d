"""Closed loop in the simulator, recorded: the detector watches the robot live and stops it at the alarm.

The control loop itself is library logic (`robofailring.jobs.closed_loop`); this module writes both runs
side by side into one `.rrd`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rfr_viz.panels.images import JPEG_MEDIA_TYPE, JPEG_QUALITY
from rfr_viz.panels.scores import set_frame_time, time_columns
from rfr_viz.panels.signals import log_signals
from rfr_viz.paths import CLOSED_LOOP_SUMMARY, PROPERTIES, UNSTOPPED, WATCHED, ClosedLoopPaths
from rfr_viz.recordings.blueprint import closed_loop_blueprint
from rfr_viz.recordings.replay import open_recording
from rfr_viz.styles import DELTA_COLOUR, STATE_COLOUR, STOP_COLOUR, VIEW_COLOURS
from robofailring.data.images import encode_jpeg
from robofailring.detection.config import DEFAULT_K
from robofailring.detection.detector import FailureDetector
from robofailring.detection.rules import PAPER
from robofailring.detection.session import StepResult
from robofailring.encoders.base import Encoder
from robofailring.encoders.cache import CachedEncoder
from robofailring.extras import needs_extra
from robofailring.jobs.closed_loop import WatchedRun, alarm, outcome_line, watch_episode
from robofailring.memory.failure import FailureMemory
from robofailring.sim import VIEWS, EpisodeResult
from robofailring.sim.episode import episode_fps

with needs_extra("viz"):
    import rerun as rr

__all__ = ["ClosedLoopResult", "run_closed_loop"]


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
    detector = FailureDetector(memory, encoder, delta=delta, k=k, rule=PAPER)  # S_t ≥ δ, as logged
    loop = watch_episode(detector, task, mode, seed, ood=ood, image_size=image_size, frames=frames)
    watched, unstopped, stop = loop.watched, loop.unstopped, loop.stop_frame
    fps = episode_fps(frames)
    blueprint = closed_loop_blueprint(
        views=VIEWS, fps=fps, length=frames, focus=stop, signals=list(unstopped.signals)
    )
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
                encoder=loop.encoder,
                delta=loop.delta,
                k=k,
                t_det=-1 if stop is None else stop,  # -1: no alarm, the watched run was not stopped
                stop_view=loop.stop_view or "",
                L=frames,
                fps=fps,
            ),
        )
        for paths, run in ((WATCHED, watched), (UNSTOPPED, unstopped)):
            _log_run(rec, paths, run, delta=loop.delta, length=frames, fps=fps, stopped=paths is WATCHED)
            log_signals(rec, run.signals, fps=fps, at=paths.signal)
        rec.log(
            CLOSED_LOOP_SUMMARY,
            rr.TextDocument(loop.summary(), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )
    return ClosedLoopResult(
        path=Path(out),
        stop_frame=stop,
        stop_view=loop.stop_view,
        watched=watched.result,
        unstopped=unstopped.result,
        length=frames,
        delta=loop.delta,
        watched_steps=watched.steps,
        unstopped_steps=unstopped.steps,
    )


def _log_run(
    rec: rr.RecordingStream,
    paths: ClosedLoopPaths,
    run: WatchedRun,
    *,
    delta: float,
    length: int,
    fps: float,
    stopped: bool,
) -> None:
    """Cameras, S_t, δ, State_t and the alarm event of one run; the watched cameras end at the stop."""
    rendered = len(run.steps)
    frames = np.arange(rendered)
    for position, view in enumerate(run.frames):
        blobs = [encode_jpeg(rgb, quality=JPEG_QUALITY) for rgb in run.frames[view]]
        rec.send_columns(
            paths.camera(view),
            indexes=time_columns(frames, fps),
            columns=rr.EncodedImage.columns(blob=blobs, media_type=[JPEG_MEDIA_TYPE] * len(blobs)),
        )
        rec.log(
            paths.detector.score(view, PAPER.name),
            rr.SeriesLines(colors=[VIEW_COLOURS[position % len(VIEW_COLOURS)]], widths=[2.0], names=[view]),
            static=True,
        )
        rec.send_columns(
            paths.detector.score(view, PAPER.name),
            indexes=time_columns(frames, fps),
            columns=rr.Scalars.columns(scalars=[step.similarity[view] for step in run.steps]),
        )
    rec.log(
        paths.detector.threshold(PAPER.name),
        rr.SeriesLines(colors=[DELTA_COLOUR], widths=[1.0], names=[f"δ = {delta:.3f}"]),
        static=True,
    )
    rec.send_columns(
        paths.detector.threshold(PAPER.name),
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
        view, top = alarm(run.steps[fired])
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
            for camera_view in run.frames:
                _log_stopped(rec, paths.stopped(camera_view), run.size, f"STOPPED at frame {fired}")
    set_frame_time(rec, rendered - 1, fps)
    rec.log(
        paths.outcome,
        rr.TextLog(
            outcome_line(paths.run, run, length),
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
