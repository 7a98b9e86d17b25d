"""The embedded simulator as a gymnasium env (`SimEnv`): its scripted policy drives the arm, one fault injected
per episode, so the demo and the tests run the monitor end to end (docs/rollouts.md, "The embedded simulator").

An observation is the three cameras (`pixels/<view>`) and the robot's signals as the simulator's datasets name
them (`joint_positions`, `gripper_width`, `ee_pose`, `goal`), with `policy_action`, the scripted policy's command
at this frame: pass it to `step` as your policy's action (the arm follows its plan whatever is passed; the action
is what the monitor records). The step after the last frame ends the episode with the goal check as
`info["is_success"]`. `SIM_ADAPTER` reads these observations.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from functools import cache
from typing import Any, Final, SupportsFloat

import numpy as np

from robofailring.extras import needs_extra
from robofailring.monitor.adapters import MappingAdapter
from robofailring.sim.cameras import VIEWS
from robofailring.sim.episode import EpisodeRun, run_episode
from robofailring.sim.perturb import KINDS, SUCCESS
from robofailring.sim.signals import SIGNALS

with needs_extra("gym"):
    import gymnasium as gym

_ACTION: Final[str] = "action"
#: How the monitor reads `SimEnv`'s observations: the names its datasets (and so its memories) use.
SIM_ADAPTER: Final[MappingAdapter] = MappingAdapter(
    name="sim",
    views={view: f"pixels/{view}" for view in VIEWS},
    signals={name: name for name in SIGNALS if name != _ACTION},
    action=_ACTION,
)


@cache
def _signal_names(task: str) -> tuple[str, ...]:
    """The signals `task`'s episodes record (a task without a place to reach has no `goal`): one tiny episode."""
    with run_episode(task, SUCCESS, 0, image_size=16, frames=2) as run:
        next(iter(run))
        return tuple(run.last_signals())


class SimEnv(gym.Env[dict[str, Any], np.ndarray]):
    """One task of the embedded simulator; each `reset` draws the episode's kind from `modes` (or takes
    `options={"mode": …}`), its scene from the seed."""

    def __init__(
        self,
        task: str = "pick_cube",
        *,
        modes: Sequence[str] = KINDS,
        image_size: int = 128,
        frames: int = 40,
        look: str = "in",
    ) -> None:
        self.task = task
        self.modes = tuple(modes)
        self.image_size, self.frames, self.look = image_size, frames, look
        image = gym.spaces.Box(0, 255, (image_size, image_size, 3), np.uint8)
        self.observation_space = gym.spaces.Dict(
            {
                "pixels": gym.spaces.Dict({view: image for view in VIEWS}),
                **{
                    name: gym.spaces.Box(-np.inf, np.inf, (len(dims),), np.float64)
                    for name, (_, dims) in SIGNALS.items()
                    if name != _ACTION and name in _signal_names(task)
                },
                "policy_action": gym.spaces.Box(-np.inf, np.inf, (len(SIGNALS[_ACTION][1]),), np.float64),
            }
        )
        self.action_space = self.observation_space["policy_action"]
        self.mode: str | None = None
        self._run: EpisodeRun | None = None
        self._frames: Iterator[dict[str, np.ndarray]] | None = None
        self._last: dict[str, Any] = {}

    def _observation(self, images: dict[str, np.ndarray]) -> dict[str, Any]:
        assert self._run is not None
        signals = self._run.last_signals()
        return {
            "pixels": images,
            **{name: values for name, values in signals.items() if name != _ACTION},
            "policy_action": signals[_ACTION],
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        super().reset(seed=seed)
        self.close()
        mode = (options or {}).get("mode") or self.modes[int(self.np_random.integers(len(self.modes)))]
        self.mode = str(mode)
        episode_seed = int(self.np_random.integers(2**31))
        self._run = run_episode(
            self.task, self.mode, episode_seed, look=self.look, image_size=self.image_size, frames=self.frames
        )
        self._frames = iter(self._run)
        self._last = self._observation(next(self._frames))
        return self._last, {"task": self.task, "mode": self.mode, "seed": episode_seed}

    def step(self, action: Any) -> tuple[dict[str, Any], SupportsFloat, bool, bool, dict[str, Any]]:
        if self._run is None or self._frames is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        images = next(self._frames, None)
        if images is not None:
            self._last = self._observation(images)
            return self._last, 0.0, False, False, {}
        result = self._run.run_to_end()
        info = {
            "is_success": result.goal.passed,
            "label": result.label,
            "onset_frame": result.onset_frame,
            "mode": self.mode or SUCCESS,
        }
        self.close()
        return self._last, float(result.goal.passed), True, False, info

    def close(self) -> None:
        if self._run is not None:
            self._run.close()
        self._run, self._frames = None, None
