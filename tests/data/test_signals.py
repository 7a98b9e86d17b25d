"""The robot's own signals read from each layout's real writer output (issue 41, item 1): names, kinds,
values and timestamps as written; bad signals listed as not read with the reason."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hdf5_writer import (
    aloha_joints,
    maniskill3_actions,
    maniskill3_qpos,
    robomimic_actions,
    robomimic_eef,
    write_aloha,
    write_maniskill3,
    write_robomimic,
)
from lerobot_writer import signal_action, write_lerobot_v3, write_lerobot_v21
from rosbag_writer import JOINTS, joint_position, write_bag
from synthetic import synthetic_frame

from robofailring import load_dataset
from robofailring.data.layouts.hdf5_signals import ALOHA_DIMS
from robofailring.data.model import Frame, Trajectory
from robofailring.data.signals import Signal, SignalKind


def _image(*args: int) -> np.ndarray:
    return synthetic_frame("pick_cube", None, args[-2], args[-1], 10, size=16)


def _read(trajectory: Trajectory) -> dict[str, tuple[SignalKind, tuple[str, ...], np.ndarray]]:
    found, skipped = trajectory.read_signals()
    assert skipped == []
    return {name: (s.kind, s.dims, s.values) for name, s in found.items()}


@pytest.mark.parametrize("version", ["v3.0", "v2.1"])
def test_lerobot_state_and_action_are_read_by_name_in_frame_order(version: str, tmp_path: Path) -> None:
    write = write_lerobot_v3 if version == "v3.0" else write_lerobot_v21
    # the data rows shuffled: each episode's rows are put back in frame order
    root = write(tmp_path / "ds", lengths=(5, 7), tasks=("a", "b"), size=16, shuffled=True)
    dataset = load_dataset(root)
    for episode, trajectory in enumerate(dataset.trajectories()):
        signals = _read(trajectory)
        assert sorted(signals) == ["action", "observation.state"]
        kind, dims, state = signals["observation.state"]
        assert (kind, dims) == (SignalKind.STATE, ("time", "episode"))
        length = trajectory.length
        np.testing.assert_array_equal(state, np.stack([np.arange(length), np.full(length, episode)], axis=1))
        kind, dims, action = signals["action"]
        assert (kind, dims) == (SignalKind.ACTION, ("x", "y", "gripper"))  # v2.1's {"motors": [...]} names
        np.testing.assert_array_equal(action, [signal_action(episode, t) for t in range(length)])
        assert trajectory.timestamps is not None
        np.testing.assert_allclose(trajectory.timestamps, np.arange(length) / trajectory.fps, atol=1e-6)


def test_robomimic_low_dim_observations_and_actions_are_signals(tmp_path: Path) -> None:
    path = write_robomimic(tmp_path / "demo.hdf5", lambda d, c, t: _image(c, t), demos=2, length=6)
    for demo, trajectory in enumerate(load_dataset(path).trajectories()):
        signals = _read(trajectory)
        assert sorted(signals) == ["actions", "obs/robot0_eef_pos"]
        kind, dims, actions = signals["actions"]
        assert (kind, dims) == (SignalKind.ACTION, tuple(str(i) for i in range(7)))
        np.testing.assert_array_equal(actions, robomimic_actions(demo, 6))
        assert signals["obs/robot0_eef_pos"][0] is SignalKind.STATE
        np.testing.assert_array_equal(signals["obs/robot0_eef_pos"][2], robomimic_eef(demo, 6))


def test_aloha_joints_are_named_and_read(tmp_path: Path) -> None:
    folder = write_aloha(
        tmp_path / "aloha", lambda e, c, t: _image(c, t), episodes=2, length=5, compress=True
    )
    for trajectory in load_dataset(folder).trajectories():
        episode = int(trajectory.episode.split("_")[-1])
        signals = _read(trajectory)
        assert sorted(signals) == ["action", "qpos", "qvel"]  # the writer stores no effort, as ACT's
        kind, dims, qpos = signals["qpos"]
        assert (kind, dims) == (SignalKind.STATE, ALOHA_DIMS) and dims[6] == "left_gripper"
        np.testing.assert_array_equal(qpos, aloha_joints(episode, 5))
        assert signals["action"][0] is SignalKind.ACTION
        np.testing.assert_array_equal(signals["action"][2], aloha_joints(episode, 5) + 1)


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_ros_joint_states_are_put_on_the_frames_timeline(kind: str, tmp_path: Path) -> None:
    """Joint states at 30 ms (their joints listed in two orders) beside a camera at 100 ms: frame i takes
    the latest joint state at or before it."""
    name = "run.bag" if kind == "ros1" else "run"
    write_bag(
        tmp_path / "bags" / name,
        kind=kind,
        topics=[("/cam/image_raw", "rgb8")],
        frames=lambda n, t: _image(n, t),
        count=6,
        joint_states=("/joint_states", 30_000_000),
    )
    (trajectory,) = load_dataset(tmp_path / "bags").trajectories()
    signals = _read(trajectory)
    assert sorted(signals) == ["/joint_states/position", "/joint_states/velocity"]  # no efforts: not a signal
    kind_, dims, position = signals["/joint_states/position"]
    assert (kind_, dims) == (SignalKind.STATE, JOINTS)
    latest = [(100 * i) // 30 for i in range(6)]  # the last message at or before frame i (30 ms apart)
    expected = [[joint_position(n, j) for j in range(len(JOINTS))] for n in latest]
    np.testing.assert_allclose(position, expected)
    np.testing.assert_array_equal(signals["/joint_states/velocity"][2], np.tile([0.0, 1.0, 2.0], (6, 1)))
    assert trajectory.timestamps is not None
    np.testing.assert_allclose(trajectory.timestamps, np.arange(6) * 0.1)


def _trajectory(**signals: np.ndarray) -> Trajectory:
    frames = [Frame.from_array(np.zeros((4, 4, 3), np.uint8))] * 5
    return Trajectory(
        task="t",
        episode="e",
        views={"front": frames, "wrist": frames[:4]},
        signals={name: Signal.from_array(name, values) for name, values in signals.items()},
    )


def test_bad_signals_are_listed_with_the_reason_and_good_ones_read() -> None:
    good = np.arange(10.0).reshape(5, 2)
    nan = good.copy()
    nan[3, 1] = np.nan
    trajectory = _trajectory(
        good=good,
        nan=nan,
        short=np.zeros((3, 2)),  # matches no view's frames (5 and 4)
        text=np.array([["a"]] * 5),
        wide=np.zeros((5, 600)),
    )
    found, skipped = trajectory.read_signals()
    assert list(found) == ["good"]
    np.testing.assert_array_equal(found["good"].values, good[:4])  # cut to the trajectory's 4 frames
    assert found["good"].columns == ["good/0", "good/1"]
    reasons = {s.reason.split("'")[1]: s.reason for s in skipped}
    assert "NaN, infinite or beyond ±3.4e+38 (the first at frame 3, dimension 1" in reasons["nan"]
    assert "3 rows, but the trajectory's views have 4 or 5 frames" in reasons["short"]
    assert "are not numbers" in reasons["text"]
    assert "600 dimensions per frame" in reasons["wide"]
    assert all(s.reason.startswith("t/e: not read: signal") for s in skipped)


def test_a_signal_named_with_the_wrong_count_of_names_is_not_read() -> None:
    trajectory = _trajectory()
    signal = Signal.from_array("state", np.zeros((5, 2)), dims=("a", "b", "c"))
    found, skipped = replace(trajectory, signals={"state": signal}).read_signals()
    assert found == {} and "2 dimensions per frame but 3 names (a, b, c)" in skipped[0].reason


def test_maniskill3_trajectories_are_read_with_cameras_signals_and_the_envs_verdict(tmp_path: Path) -> None:
    path = write_maniskill3(
        tmp_path / "ms", lambda e, c, t: _image(c, t), episodes=2, steps=5, success=[True, False]
    )
    dataset = load_dataset(path.parent)
    assert dataset.layout == "maniskill3" and dataset.skipped == []
    first, second = dataset.trajectories()
    assert (first.key, first.outcome.value, second.outcome.value) == (
        "PickCube-v1/traj_0",
        "success",
        "failure",
    )
    assert list(first.views) == ["base_camera"] and first.length == 6
    signals = _read(second)
    assert sorted(signals) == [
        "actions",
        "agent/qpos",
        "agent/qvel",
        "extra/goal_pos",
        "extra/is_grasped",
        "extra/tcp_pose",
    ]
    assert signals["extra/tcp_pose"][1] == ("x", "y", "z", "qw", "qx", "qy", "qz")
    assert signals["extra/goal_pos"][0] is SignalKind.OTHER and signals["actions"][0] is SignalKind.ACTION
    np.testing.assert_array_equal(signals["agent/qpos"][2], maniskill3_qpos(1, 6))
    actions = maniskill3_actions(1, 5)  # frame t takes the action that led to it, frame 0 the first
    np.testing.assert_array_equal(signals["actions"][2], np.concatenate([actions[:1], actions]))
    assert load_dataset(path).layout == "maniskill3"  # the file alone, too
