"""The keyframe controller: interpolates end-effector poses, solves IK, fires gripper events."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from robofailring.sim.geometry import Pose, Quat, Vec3, slerp
from robofailring.sim.plan import Keyframe, Plan
from robofailring.sim.robot import Panda
from robofailring.sim.scene import PHYSICS_HZ

#: IK is solved every CONTROL_EVERY physics steps (120 Hz at 240 Hz physics).
CONTROL_EVERY = 2


def _smooth(u: float) -> float:
    u = min(1.0, max(0.0, u))
    return u * u * (3.0 - 2.0 * u)


@dataclass(frozen=True)
class Segment:
    """The motion towards one keyframe: from `start` (s) for its duration, then its action and hold."""

    keyframe: Keyframe
    origin: Pose
    start: float

    @property
    def arrival(self) -> float:
        return self.start + self.keyframe.duration

    @property
    def end(self) -> float:
        return self.arrival + self.keyframe.hold

    def pose_at(self, t: float) -> tuple[Vec3, Quat]:
        """Rising moves lift first, descending moves travel first, level moves go straight."""
        s = (t - self.start) / self.keyframe.duration
        (x0, y0, z0), (x1, y1, z1) = self.origin.position, self.keyframe.position
        if z1 > z0 + 0.02:
            along, up = _smooth((s - 0.25) / 0.75), _smooth(s / 0.6)
        elif z1 < z0 - 0.02:
            along, up = _smooth(s / 0.6), _smooth((s - 0.25) / 0.75)
        else:
            along = up = _smooth(s)
        position = (x0 + along * (x1 - x0), y0 + along * (y1 - y0), z0 + up * (z1 - z0))
        return position, slerp(self.origin.orientation, self.keyframe.orientation, _smooth(s))


class Controller:
    """Runs a plan on a Panda, one physics step at a time; after the last keyframe it holds still."""

    def __init__(self, client: Any, robot: Panda, plan: Plan, *, graspable: Sequence[int], half_size: float):
        self.client = client
        self.robot = robot
        self.graspable = tuple(graspable)
        self.half_size = half_size
        self.step_index = 0
        self.segments: list[Segment] = []
        origin, t = robot.ee_pose(), 0.0
        for keyframe in plan:
            self.segments.append(Segment(keyframe, origin, t))
            origin = Pose(keyframe.position, keyframe.orientation)
            t += keyframe.duration + keyframe.hold
        self._events = sorted(self._schedule(), key=lambda e: e[0])
        self.grasped: list[int] = []
        self.released = 0

    @property
    def time(self) -> float:
        return self.step_index / PHYSICS_HZ

    @property
    def plan_end(self) -> float:
        return self.segments[-1].end if self.segments else 0.0

    def _schedule(self) -> list[tuple[int, int, str]]:
        events = []
        for i, seg in enumerate(self.segments):
            if seg.keyframe.release_at is not None:
                at = seg.start + seg.keyframe.release_at * seg.keyframe.duration
                events.append((round(at * PHYSICS_HZ), i, "open"))
            if seg.keyframe.action is not None:
                events.append((round(seg.arrival * PHYSICS_HZ), i, seg.keyframe.action))
        return events

    def _target(self, t: float) -> tuple[Vec3, Quat]:
        for seg in self.segments:
            if t < seg.arrival:
                return seg.pose_at(t)
            if t < seg.end:
                break
        else:
            seg = self.segments[-1]
        return seg.keyframe.position, seg.keyframe.orientation

    def _fire(self, action: str) -> None:
        if action == "open":
            if self.robot.held is not None:
                self.released += 1
            self.robot.open()
            return
        body = next((b for b in self.graspable if self.robot.graspable(b, half_size=self.half_size)), None)
        if body is not None:
            self.grasped.append(body)
        self.robot.close_on(body, half_size=self.half_size)

    def command(self) -> tuple[Vec3, Quat, float]:
        """What the arm is commanded now: the end-effector target pose and the gripper's width (m)."""
        position, orientation = self._target(self.time)
        return position, orientation, 2 * self.robot.finger_target

    def step(self) -> None:
        """Advance one physics step: fire due gripper events, steer the arm, simulate."""
        if self.segments and self.step_index % CONTROL_EVERY == 0:
            self.robot.drive_pose(*self._target(self.time))
        while self._events and self._events[0][0] <= self.step_index:
            _, _, action = self._events.pop(0)
            self._fire(action)
        self.client.stepSimulation()
        self.step_index += 1
