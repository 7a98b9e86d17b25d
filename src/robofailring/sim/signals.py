"""What the simulated robot records beside its cameras at each rendered frame: its joint positions, the
gripper's width, the end effector's pose, the commanded action and the task's goal (where it has one)."""

from __future__ import annotations

from typing import Any, Final

import numpy as np

from robofailring.data.layouts.project import PROJECT_SIGNALS
from robofailring.data.signals import SignalKind, SignalValues
from robofailring.sim.robot import ARM_JOINTS, FINGER_JOINTS, Panda
from robofailring.sim.tasks import Layout

#: name -> (kind, dimension names), in the order they are written: the project layout's own record of them.
SIGNALS: Final[dict[str, tuple[str, tuple[str, ...]]]] = PROJECT_SIGNALS


def goal_of(layout: Layout) -> tuple[float, float] | None:
    """Where the task's object must end up on the table: the goal disc or tray, the cube to stack on; None
    when the goal is not a place (lifting)."""
    if layout.goal != (0.0, 0.0):
        return layout.goal
    second = layout.starts.get("second")
    return None if second is None else (second[0], second[1])


def signal_row(
    client: Any, robot: Panda, action: tuple[Any, Any, float], goal: tuple[float, float] | None
) -> dict[str, np.ndarray]:
    """One frame's values of every signal: `action` is the commanded (position, orientation, gripper width);
    the goal only where the task has one."""
    joints = [float(client.getJointState(robot.body, j)[0]) for j in (*ARM_JOINTS, *FINGER_JOINTS)]
    pose = robot.ee_pose()
    position, orientation, width = action
    return {
        "joint_positions": np.asarray(joints),
        "gripper_width": np.asarray([joints[-2] + joints[-1]]),
        "ee_pose": np.asarray([*pose.position, *pose.orientation]),
        "action": np.asarray([*position, *orientation, width]),
    } | ({} if goal is None else {"goal": np.asarray(goal, dtype=np.float64)})


def stacked(rows: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Rows of `signal_row` as one (frames, D) float32 array per signal."""
    names = [name for name in SIGNALS if rows and name in rows[0]]
    return {name: np.stack([row[name] for row in rows]).astype(np.float32) for name in names}


def named(arrays: dict[str, np.ndarray]) -> dict[str, SignalValues]:
    """`stacked` arrays with their kinds and dimension names, as a dataset's signals are read."""
    return {
        name: SignalValues(name, SignalKind(SIGNALS[name][0]), SIGNALS[name][1], values.astype(np.float64))
        for name, values in arrays.items()
    }
