"""The observation conventions the monitor reads (issue 52, item 1): LeRobot, ManiSkill3, robosuite/LIBERO
(with their old 4-tuple step) and a user's mapping, each giving the views and signal names the project's loader of
that layout gives, so that a memory built from such a dataset meets the same names live."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rollout_env import TASK
from synthetic import synthetic_frame

from robofailring import (
    FailureDetector,
    LegacyEnv,
    LeRobotAdapter,
    ManiSkillAdapter,
    MappingAdapter,
    RobosuiteAdapter,
    RolloutError,
    RolloutMonitor,
    load_dataset,
)
from robofailring.data.signals import SignalKind
from robofailring.monitor.adapters import adapter_for

FRAME = synthetic_frame(TASK, None, 0, 0, 8)  # (48, 48, 3) uint8


def test_lerobot_processed_and_raw_observations() -> None:
    chw = (FRAME.transpose(2, 0, 1)[None] / 255.0).astype(
        np.float32
    )  # LeRobot's processed: (1, 3, H, W) in [0, 1]
    observed = LeRobotAdapter().observe(
        {"observation.images.top": chw, "observation.image": FRAME, "observation.state": np.ones((1, 4))},
        step=0,
    )
    assert sorted(observed.views) == ["image", "top"]
    assert np.abs(observed.views["top"].astype(int) - FRAME).max() <= 1 and observed.views["image"].shape == (
        48,
        48,
        3,
    )
    assert observed.signals["observation.state"].tolist() == [1.0] * 4
    raw = LeRobotAdapter().observe({"pixels": {"top": FRAME}, "agent_pos": np.zeros(2)}, step=0)
    assert list(raw.views) == ["top"] and raw.signals["observation.state"].tolist() == [0.0, 0.0]
    assert LeRobotAdapter().action_signals(np.array([0.5, 1.0]), step=0)["action"].tolist() == [0.5, 1.0]
    assert LeRobotAdapter().kind("action") is SignalKind.ACTION
    assert LeRobotAdapter().kind("observation.state") is SignalKind.STATE


def test_maniskill_batched_observations_of_one_env() -> None:
    observation = {
        "sensor_data": {"base_camera": {"rgb": FRAME[None], "depth": np.zeros((1, 48, 48, 1))}},
        "agent": {"qpos": np.arange(9.0)[None], "qvel": np.zeros((1, 9))},
        "extra": {"tcp_pose": np.zeros((1, 7))},
    }
    observed = ManiSkillAdapter().observe(observation, step=0)
    assert list(observed.views) == ["base_camera"] and np.array_equal(observed.views["base_camera"], FRAME)
    assert sorted(observed.signals) == ["agent/qpos", "agent/qvel", "extra/tcp_pose"]
    assert ManiSkillAdapter().action_signals(np.zeros((1, 8)), step=0)["actions"].shape == (8,)
    batch = {"sensor_data": {"base_camera": {"rgb": np.stack([FRAME, FRAME])}}}
    with pytest.raises(RolloutError, match=r"a batch of 2 envs in one observation; .*VectorRolloutMonitor"):
        ManiSkillAdapter().observe(batch, step=4)
    assert isinstance(adapter_for(observation), ManiSkillAdapter)


def test_robosuite_images_turned_upright_and_low_dim_as_robomimic_names_them() -> None:
    observation = {
        "agentview_image": FRAME[::-1],
        "robot0_eye_in_hand_image": FRAME[::-1],
        "robot0_eef_pos": np.zeros(3),
        "robot0_gripper_qpos": np.zeros(2),
        "object-state": np.zeros(10),
    }
    observed = RobosuiteAdapter().observe(observation, step=0)
    assert sorted(observed.views) == ["agentview", "robot0_eye_in_hand"]
    assert np.array_equal(observed.views["agentview"], FRAME)
    assert sorted(observed.signals) == ["obs/robot0_eef_pos", "obs/robot0_gripper_qpos"]
    assert isinstance(adapter_for(observation), RobosuiteAdapter)
    with pytest.raises(RolloutError, match=r"follows none of the conventions .* its keys: robot0_eef_pos"):
        adapter_for({"robot0_eef_pos": np.zeros(3)})


class OldApiEnv:
    """An env of the old API, as robosuite's and LIBERO's are: `reset() -> obs`, a 4-tuple `step`, the
    language instruction as an attribute and the goal check as `check_success()`."""

    language_instruction = TASK

    def __init__(self, length: int = 4) -> None:
        self.length, self.t = length, 0

    def observation(self) -> dict[str, Any]:
        return {
            "agentview_image": synthetic_frame(TASK, None, 0, self.t, self.length)[::-1],
            "robot0_eef_pos": np.zeros(3),
        }

    def reset(self) -> dict[str, Any]:
        self.t = 0
        return self.observation()

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, dict[str, Any]]:
        self.t += 1
        return self.observation(), 0.0, self.t >= self.length, {}

    def check_success(self) -> bool:
        return True


def test_an_old_api_env_runs_under_the_monitor_with_its_language_and_goal_check(
    detector: FailureDetector, tmp_path: Path
) -> None:
    with RolloutMonitor(
        OldApiEnv(), detector, out=tmp_path / "out"
    ) as env:  # put in a LegacyEnv, adapter: auto
        assert isinstance(env.env, LegacyEnv)
        env.reset()
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(np.zeros(7))
            done = terminated or truncated
        assert terminated and info["is_success"] is True and set(info["robofailring"].scores) == {"agentview"}
    (trajectory,) = load_dataset(tmp_path / "out" / "episodes").trajectories()
    assert trajectory.task == TASK and trajectory.outcome.value == "success" and trajectory.length == 4
    assert np.array_equal(trajectory.views["agentview"][0].load(), synthetic_frame(TASK, None, 0, 0, 4))
    signals, _ = trajectory.read_signals()
    assert (
        signals["actions"].kind is SignalKind.ACTION
        and signals["obs/robot0_eef_pos"].kind is SignalKind.STATE
    )


def test_a_mapping_names_nested_keys() -> None:
    adapter = MappingAdapter(views={"front": "cameras/front"}, signals={"joints": "robot/q"}, action=None)
    observed = adapter.observe({"cameras": {"front": FRAME}, "robot": {"q": [0.1, 0.2]}}, step=2)
    assert list(observed.views) == ["front"] and observed.signals["joints"].tolist() == [0.1, 0.2]
    assert adapter.action_signals(np.zeros(2), step=2) == {}
    with pytest.raises(
        RolloutError, match=r"step 2: the observation has no 'cameras/front' .* its keys: robot/q"
    ):
        adapter.observe({"robot": {"q": [0.1]}}, step=2)
