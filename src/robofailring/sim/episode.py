"""One simulated episode, stepped frame by frame: build, perturb, run, render, check the goal."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Literal

import numpy as np

from robofailring.sim.appearance import look_mode, make_look
from robofailring.sim.cameras import CameraRig
from robofailring.sim.controller import Controller
from robofailring.sim.perturb import SUCCESS, Perturbation, apply, choose, onset_time, resolve_mode
from robofailring.sim.robot import Panda
from robofailring.sim.scene import PHYSICS_HZ, add_table, connect
from robofailring.sim.signals import goal_of, signal_row, stacked
from robofailring.sim.tasks import TASK_CLASSES, TASKS, GoalCheck

#: Simulated length of every episode (s): the plan takes about 5 s, the rest lets objects settle.
DURATION_S = 6.0


@dataclass(frozen=True)
class EpisodeResult:
    """How an episode ended: the goal check decides the outcome; a failure keeps its label."""

    task: str
    seed: int
    perturbation: Perturbation | None
    goal: GoalCheck
    frames: int
    stopped_early: bool
    #: The first rendered frame after the perturbation begins to act (None: no perturbation, or
    #: it begins after the last rendered frame).
    perturbation_frame: int | None = None

    @property
    def outcome(self) -> Literal["success", "failure"]:
        return "success" if self.goal.passed else "failure"

    @property
    def label(self) -> str | None:
        """The failure symbol; None when the goal was reached (even under a perturbation) and for an
        unperturbed run that missed it (the dataset writer retries those with another seed)."""
        if self.goal.passed or self.perturbation is None:
            return None
        return self.perturbation.symbol

    @property
    def onset_frame(self) -> int | None:
        """Where the failure starts: the perturbation's first frame, for a failure only."""
        return self.perturbation_frame if self.label is not None else None


def frame_steps(frames: int) -> list[int]:
    """Physics-step indices of the rendered frames: the first at t = 0, the last at DURATION_S."""
    total = round(DURATION_S * PHYSICS_HZ)
    if frames < 2:
        raise ValueError(f"an episode needs at least 2 frames, got {frames}")
    return [round(i * total / (frames - 1)) for i in range(frames)]


def frame_after(steps: list[int], seconds: float | None) -> int | None:
    """The first rendered frame whose physics step comes after the moment `seconds` (None: none does).

    A frame at step s shows the scene after s physics steps; what is commanded at step e acts in
    step e and is seen from the first frame whose step is past e."""
    if seconds is None:
        return None
    commanded = math.floor(seconds * PHYSICS_HZ + 1e-9)
    return next((index for index, step in enumerate(steps) if step > commanded), None)


def episode_fps(frames: int) -> float:
    return round((frames - 1) / DURATION_S, 4)


class EpisodeRun:
    """A running episode: iterate for ``{view: rgb}`` per frame; ``stop()`` ends it early.

    >>> with run_episode("pick_cube", "grasp", seed=3, frames=12) as run:  # doctest: +SKIP
    ...     for images in run:
    ...         if detector_fired(images):
    ...             run.stop()
    ...     print(run.result.outcome, run.result.label)
    """

    def __init__(
        self,
        task: str,
        mode: str,
        seed: int,
        *,
        ood: bool = False,
        look: str = "in",
        image_size: int = 128,
        frames: int = 40,
        waypoint: int | None = None,
    ) -> None:
        if task not in TASK_CLASSES:
            raise ValueError(f"unknown task {task!r}; expected one of {list(TASKS)}")
        self.task_name = task
        self.seed = seed
        self._steps = frame_steps(frames)
        rng = np.random.default_rng(seed)
        self.mode = resolve_mode(mode, rng)
        self.perturbation = choose(task, self.mode, rng, waypoint=waypoint)
        self.fps = episode_fps(frames)
        self.look = make_look(look_mode(look, ood=ood), rng=rng)
        self._client: Any = connect()
        try:
            add_table(self._client, self.look)
            self._robot = Panda(self._client)
            self._task = TASK_CLASSES[task]()
            self._layout = self._task.build(self._client, self.look, rng)
            obj = "distractor" if self.mode == "wrong_object" else "target"
            plan = apply(self._task.plan(self._layout, obj=obj), self.perturbation)
            self.perturbation_frame = frame_after(
                self._steps, onset_time(self._task.plan(self._layout), plan)
            )
            self._controller = Controller(
                self._client, self._robot, plan, graspable=self._layout.cubes, half_size=self._layout.size / 2
            )
            self._cameras = CameraRig(self._client, self.look, image_size=image_size)
        except BaseException:
            self._client.disconnect()
            raise
        self._stop = False
        self._iterator: Iterator[dict[str, np.ndarray]] | None = None
        self._rendered = 0
        self._signal_rows: list[dict[str, np.ndarray]] = []
        self.result: EpisodeResult | None = None

    @property
    def attempted_label(self) -> str | None:
        """The symbol the perturbation would carry if it makes the episode fail (None for success)."""
        return None if self.perturbation is None else self.perturbation.symbol

    @property
    def frames(self) -> int:
        return len(self._steps)

    def signals(self) -> dict[str, np.ndarray]:
        """The robot's signals at every frame rendered so far (`robofailring.sim.signals.SIGNALS`): (frames, D)."""
        return stacked(self._signal_rows)

    def last_signals(self) -> dict[str, np.ndarray]:
        """The robot's signals at the frame just rendered (the step API's `signals=`)."""
        return dict(self._signal_rows[-1]) if self._signal_rows else {}

    def __iter__(self) -> Iterator[dict[str, np.ndarray]]:
        if self._iterator is None:
            self._iterator = self._frames()
        return self._iterator

    def _frames(self) -> Iterator[dict[str, np.ndarray]]:
        try:
            for step in self._steps:
                while self._controller.step_index < step:
                    self._controller.step()
                images = self._cameras.capture(self._robot)
                self._signal_rows.append(
                    signal_row(self._client, self._robot, self._controller.command(), goal_of(self._layout))
                )
                self._rendered += 1
                yield images
                if self._stop:
                    break
        finally:
            self._finish()

    def stop(self) -> None:
        """End the episode at the current frame: the goal is checked on the scene as it is now and
        `result` is set; iteration ends at the next step."""
        self._stop = True
        self._finish()

    def _finish(self) -> None:
        if self.result is not None:
            return
        if self._client is None:
            raise RuntimeError("the episode was closed before its goal was checked")
        goal = self._task.check(self._client, self._layout)
        self.result = EpisodeResult(
            task=self.task_name,
            seed=self.seed,
            perturbation=self.perturbation,
            goal=goal,
            frames=self._rendered,
            stopped_early=self._rendered < len(self._steps),
            perturbation_frame=(
                self.perturbation_frame
                if self.perturbation_frame is not None and self.perturbation_frame < self._rendered
                else None
            ),
        )

    def run_to_end(self) -> EpisodeResult:
        """Finish the episode (rendering the remaining frames) and return its result."""
        for _ in self:
            pass
        self._finish()
        assert self.result is not None
        return self.result

    def close(self) -> None:
        """Check the goal if not done yet and release the physics client."""
        self._finish()
        if self._client is not None:
            self._client.disconnect()
            self._client = None

    def __enter__(self) -> EpisodeRun:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.close()


def run_episode(
    task: str,
    mode: str = SUCCESS,
    seed: int = 0,
    *,
    ood: bool = False,
    look: str = "in",
    image_size: int = 128,
    frames: int = 40,
    waypoint: int | None = None,
) -> EpisodeRun:
    """Start one episode: `mode` is ``success``, a failure family (``rotation``) or a concrete mode
    (``rotation_x``); the axis, waypoint and object poses are drawn from `seed`. `look` is ``in``,
    ``ood`` or ``random`` (`robofailring.sim.appearance`); ``ood=True`` is ``look="ood"``."""
    return EpisodeRun(
        task, mode, seed, ood=ood, look=look, image_size=image_size, frames=frames, waypoint=waypoint
    )
