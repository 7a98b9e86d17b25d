"""The monitor's fixtures: a pixels memory with the robot's signals, saved, and a minimal gymnasium env that
plays the synthetic runs that memory was built from (tests/synthetic.py), frame by frame."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from synthetic import VIEWS, robot_signals, synthetic_frame, write_project_dataset

from robofailring import CachedEncoder, FailureDetector, load_dataset, load_encoder
from robofailring.memory.builder import Provenance, build_memories

gym = pytest.importorskip("gymnasium")

LENGTH = 8
TASK = "pick_cube"


@pytest.fixture(scope="session")
def monitor_memory_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The train half of a signals dataset (grasp and slip failures, successes) as a saved pixels memory."""
    root = write_project_dataset(
        tmp_path_factory.mktemp("monitor-data") / "data",
        tasks=(TASK,),
        symbols=("grasp_wp2", "slip_wp3"),
        episodes=4,
        length=LENGTH,
        signals=True,
    )
    train = [t for t in load_dataset(root).trajectories() if t.split == "train"]
    encoder = CachedEncoder(load_encoder("pixels"), enabled=False)
    memory, _ = build_memories(train, encoder, provenance=Provenance(data=root, encoder="pixels"))
    return memory.save(tmp_path_factory.mktemp("monitor-memory") / "memory")


@pytest.fixture()
def detector(monitor_memory_dir: Path) -> FailureDetector:
    from robofailring import open_detector

    return open_detector(monitor_memory_dir, gamma=0.05)


class ReplayEnv(gym.Env):  # type: ignore[misc]
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


@pytest.fixture()
def replay_env() -> ReplayEnv:
    return ReplayEnv(TEST_RUNS)
