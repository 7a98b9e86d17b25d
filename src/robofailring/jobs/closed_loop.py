"""The closed-loop watcher's control loop: the detector watches a simulated robot and stops it at the alarm.

Library logic only (no Rerun): `watch_episode` runs one episode twice, once stopped at the first alarm
(State_t = 1) and once left to run, and returns both runs; `rfr_viz.recordings.closed_loop` records them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robofailring.data.signals import SignalValues
from robofailring.detection.detector import FailureDetector
from robofailring.detection.session import StepResult
from robofailring.memory.failure import Neighbor
from robofailring.sim.episode import EpisodeResult, run_episode
from robofailring.sim.signals import named
from robofailring.sim.tasks import GoalCheck


@dataclass(frozen=True)
class WatchedRun:
    """One run of the episode: the detector's steps, the RGB frames per view and the goal check."""

    steps: list[StepResult]
    frames: dict[str, list[np.ndarray]] = field(repr=False)
    size: tuple[int, int]  # width, height of the camera images
    result: EpisodeResult
    signals: dict[str, SignalValues] = field(
        default_factory=dict, repr=False
    )  # the robot's, every frame rendered

    @property
    def fired_at(self) -> int | None:
        """The first frame with State_t = 1, None without an alarm."""
        return next((step.t for step in self.steps if step.alarm), None)


@dataclass(frozen=True)
class ClosedLoop:
    """Both runs of one episode: `watched` stopped at the first alarm, `unstopped` left to run all L frames."""

    task: str
    mode: str
    seed: int
    encoder: str  # the encoder's identity
    delta: float
    k: int
    length: int  # L: frames of the full episode
    watched: WatchedRun
    unstopped: WatchedRun

    @property
    def stop_frame(self) -> int | None:
        """The first alarm (State_t = 1), where the watched run was stopped."""
        return self.watched.fired_at

    @property
    def stop_view(self) -> str | None:
        """The view with the highest S_t among those over δ at the stop."""
        stop = self.stop_frame
        return None if stop is None else alarm(self.watched.steps[stop])[0]

    @property
    def saving_ratio(self) -> float | None:
        """T_s = 1 − t_det / L (paper Table 2), None without an alarm."""
        stop = self.stop_frame
        return None if stop is None else 1.0 - stop / self.length

    def summary(self) -> str:
        """Markdown: both runs' goal checks side by side, then what the detector retrieved at the stop."""
        length = len(self.unstopped.steps)
        lines = [
            f"**{self.task} · {self.mode} · seed {self.seed}** · `{self.encoder}` · δ = {self.delta:.3f} · "
            f"K = {self.k} · L = {length}",
            "",
        ]
        lines += ["| run | frames | goal check | label |", "|---|---|---|---|"]
        for name, run in (("watched", self.watched), ("unstopped", self.unstopped)):
            values = goal_values(run.result.goal)
            lines.append(
                f"| {name} | {run.result.frames}/{length}{' (stopped)' if run.result.stopped_early else ''} | "
                f"**{run.result.outcome}** ({values}) | {run.result.label or '—'} |"
            )
        lines.append("")
        stop = self.stop_frame
        if stop is None:
            peak = max(max(step.similarity.values()) for step in self.unstopped.steps)
            lines.append(f"**No alarm**: the highest S_t is {peak:.3f} < δ, so the robot was never stopped.")
        else:
            view, top = alarm(self.watched.steps[stop])
            lines.append(
                f"**STOP at frame {stop}** (T_s = {1 - stop / length:.2f}), view {view}, "
                f"S_t = {self.watched.steps[stop].similarity[view]:.3f}; nearest: {top.entry.symbol} "
                f"({top.entry.episode}, {top.entry.view}): *{top.entry.description}*"
            )
        return "\n".join(lines)


def watch_episode(
    detector: FailureDetector,
    task: str,
    mode: str,
    seed: int,
    *,
    ood: bool = False,
    image_size: int = 128,
    frames: int = 40,
) -> ClosedLoop:
    """Run one simulated episode twice with `detector`: stopped at the first alarm, then left to run.

    Both runs are the same episode (same task, mode and seed); the unstopped one is scored but never stopped.
    """
    watched, unstopped = (
        run_watched(detector, task, mode, seed, act=act, ood=ood, image_size=image_size, frames=frames)
        for act in (True, False)
    )
    return ClosedLoop(
        task=task,
        mode=mode,
        seed=seed,
        encoder=detector.encoder.identity,
        delta=detector.delta,
        k=detector.k,
        length=frames,
        watched=watched,
        unstopped=unstopped,
    )


def run_watched(
    detector: FailureDetector,
    task: str,
    mode: str,
    seed: int,
    *,
    act: bool,
    ood: bool = False,
    image_size: int = 128,
    frames: int = 40,
) -> WatchedRun:
    """The control loop: every frame goes to the detector; with `act`, the first alarm stops the robot."""
    session = detector.session(task)
    steps: list[StepResult] = []
    kept: dict[str, list[np.ndarray]] = {}
    size = (image_size, image_size)
    with run_episode(task, mode, seed, ood=ood, image_size=image_size, frames=frames) as run:
        for images in run:
            step = session.step(images, signals=run.last_signals())
            steps.append(step)
            for view, rgb in images.items():
                kept.setdefault(view, []).append(rgb)
                size = (rgb.shape[1], rgb.shape[0])
            if act and step.alarm:
                run.stop()  # the goal is checked on the scene as the robot leaves it now
        result = run.run_to_end()
        signals = named(run.signals())
    return WatchedRun(steps=steps, frames=kept, size=size, result=result, signals=signals)


def alarm(step: StepResult) -> tuple[str, Neighbor]:
    """The view that fired with the highest score, and its nearest memory entry."""
    view = step.camera_view  # the firing camera, or the highest one when the robot's signals fired
    assert view is not None, "alarm() of a step that did not fire"
    return view, step.neighbors[view][0]


def goal_values(goal: GoalCheck) -> str:
    """The numbers the goal check decided from, e.g. "lift_m = 0.000" (never "-0.000")."""
    return ", ".join(f"{key} = {round(value, 3) + 0.0:.3f}" for key, value in goal.values.items())


def outcome_line(name: str, run: WatchedRun, length: int) -> str:
    """One run's goal check in a sentence: frames run, outcome, label and the goal's numbers."""
    values = goal_values(run.result.goal)
    label = f" ({run.result.label})" if run.result.label else ""
    return (
        f"{name} run ended after {run.result.frames}/{length} frames: goal check "
        f"{run.result.outcome.upper()}{label}; {values}"
    )
