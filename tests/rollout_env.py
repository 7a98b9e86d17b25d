"""A minimal gymnasium env for the rollout monitor's tests (tests/monitor): it plays the synthetic runs of
`synthetic.write_project_dataset` frame by frame, as a LeRobot env's observations."""

from __future__ import annotations

from typing import Any

import numpy as np
from environment import require_module
from synthetic import VIEWS, robot_signals, synthetic_frame

LENGTH = 8
TASK = "pick_cube"
gym = require_module("gymnasium", 'pip install "robofailring[gym]"')


class ReplayEnv(gym.Env[dict[str, Any], np.ndarray]):
    """A minimal env: each episode plays one synthetic run (a success, or a `grasp`/`slip` failure) as a LeRobot
    observation (`observation.images.<view>`, `observation.state` the gripper width); `expert_action()` is the
    run's commanded action now. The step after the last frame ends it, with `is_success` in its info."""

    def __init__(self, runs: list[tuple[str | None, int]], *, length: int = LENGTH, size: int = 48) -> None:
        self.runs, self.length, self.size = runs, length, size
        self.episode = -1
        self.t = 0
        self.observation_space = gym.spaces.Dict(
            {
                **{
                    f"observation.images.{view}": gym.spaces.Box(0, 255, (size, size, 3), np.uint8)
                    for view in VIEWS
                },
                "observation.state": gym.spaces.Box(-1, 1, (1,), np.float64),
            }
        )
        self.action_space = gym.spaces.Box(-1, 1, (2,), np.float64)
        self.task = TASK

    @property
    def run(self) -> tuple[str | None, int]:
        return self.runs[self.episode % len(self.runs)]

    def observation(self) -> dict[str, np.ndarray]:
        symbol, shift = self.run
        t = min(self.t, self.length - 1)
        state = robot_signals(symbol, self.length, shift)["gripper_width"][t]
        return {
            **{
                f"observation.images.{view}": synthetic_frame(
                    TASK, symbol, number, t + shift, self.length + shift, size=self.size
                )
                for number, view in enumerate(VIEWS)
            },
            "observation.state": state,
        }

    def expert_action(self) -> np.ndarray:
        symbol, shift = self.run
        return robot_signals(symbol, self.length, shift)["action"][min(self.t, self.length - 1)]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        self.episode += 1
        self.t = 0
        return self.observation(), {}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self.t += 1
        done = self.t >= self.length
        info = {"is_success": self.run[0] is None} if done else {}
        return self.observation(), 0.0, done, False, info


#: The test half of the dataset (odd episodes): (symbol, its shift), as write_project_dataset writes them.
TEST_RUNS: list[tuple[str | None, int]] = [
    (symbol, episode) for symbol in ("grasp_wp2", "slip_wp3", None) for episode in (1, 3)
]
ADAPTER_SIGNALS = {"gripper_width": "observation.state"}
