"""Keyframe plans: one end-effector keyframe per FailGen waypoint (wp1..wp5)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

from robofailring.sim.geometry import IDENTITY, Quat, Vec3, quat_multiply, top_down

GripperAction = Literal["close", "open"]
#: FailGen's execution stages (grounding Table 5): wp1 approach, wp2 grasp/interaction,
#: wp3 manipulation/movement, wp4 near-goal placement, wp5 completion/retraction.
WAYPOINTS: tuple[int, ...] = (1, 2, 3, 4, 5)


@dataclass(frozen=True)
class Keyframe:
    """A target pose of the grasp point, reached in `duration` s, then a gripper action and a pause.

    The gripper action and the pause belong to the keyframe's slot in the timeline, the pose to
    the waypoint: a wrong sequence swaps poses between slots and keeps the actions in place.
    """

    stage: int
    position: Vec3
    yaw: float
    duration: float
    action: GripperAction | None = None
    hold: float = 0.0
    #: World-frame rotation applied on top of the straight-down orientation (perturbations).
    extra: Quat = IDENTITY
    #: Slip: the grasp opens at this fraction of the motion towards the keyframe.
    release_at: float | None = None

    @property
    def orientation(self) -> Quat:
        return quat_multiply(self.extra, top_down(self.yaw))

    def moved(self, dx: float = 0.0, dy: float = 0.0, dz: float = 0.0) -> Keyframe:
        x, y, z = self.position
        return replace(self, position=(x + dx, y + dy, z + dz))


Plan = tuple[Keyframe, ...]


def plan_duration(plan: Plan) -> float:
    return sum(k.duration + k.hold for k in plan)
