"""The tabletop tasks: object layout (jittered by seed), the nominal keyframe plan and the goal check."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Final

import numpy as np

from robofailring.sim.appearance import Look
from robofailring.sim.geometry import tilt_deg, wrap_quarter
from robofailring.sim.plan import Keyframe, Plan
from robofailring.sim.scene import (
    TABLE_TOP,
    TRAY_INNER,
    TRAY_THICK,
    TRAY_WALL,
    add_cube,
    add_goal_marker,
    add_tray,
)

#: Heights of the grasp point above a cube's centre when approaching and when carrying.
APPROACH = 0.12
CARRY = 0.2
#: How far the hand draws back towards the robot when retracting (wp5), clearing the view.
RETREAT = 0.12
#: The robot's start pose (Panda home: grasp point above the table, fingers down, yaw 0).
HOME_YAW = 0.0


@dataclass(frozen=True)
class GoalCheck:
    """The simulator's verdict on the task goal, with the numbers it was decided from."""

    passed: bool
    values: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"passed": self.passed, **{k: round(v, 4) for k, v in self.values.items()}}


@dataclass(frozen=True)
class Layout:
    """The objects of one episode: body ids and start poses (x, y, yaw) by role."""

    bodies: dict[str, int]
    starts: dict[str, tuple[float, float, float]]
    size: float
    goal: tuple[float, float] = (0.0, 0.0)

    @property
    def cubes(self) -> tuple[int, ...]:
        """Every body the gripper could grasp."""
        return tuple(self.bodies[r] for r in ("target", "second", "distractor") if r in self.bodies)


def _jitter(rng: np.random.Generator, x: float, y: float, spread: float) -> tuple[float, float]:
    dx, dy = rng.uniform(-spread, spread, size=2)
    return x + float(dx), y + float(dy)


def _skewed_yaw(rng: np.random.Generator) -> float:
    """A cube yaw 25-40 degrees off square, so a grasp without turning the hand fails."""
    return float(rng.choice([-1.0, 1.0]) * rng.uniform(math.radians(25), math.radians(40)))


def _cube(
    client: Any, rng: np.random.Generator, look: Look, xy: tuple[float, float], yaw: float, role: str
) -> int:
    rgba = {"target": look.target_rgba, "second": look.second_rgba, "distractor": look.distractor_rgba}[role]
    return add_cube(client, size=look.cube_size, position=xy, yaw=yaw, rgba=rgba)


def _pose(client: Any, body: int) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    position, orientation = client.getBasePositionAndOrientation(body)
    return tuple(position), tuple(orientation)


def _grasp_keyframes(x: float, y: float, yaw: float, half: float) -> tuple[Keyframe, Keyframe]:
    """wp1 above the cube, turned square to it; wp2 down at its centre, closing."""
    wp1 = Keyframe(1, (x, y, half + APPROACH), wrap_quarter(yaw), duration=1.0)
    wp2 = Keyframe(2, (x, y, half), wrap_quarter(yaw), duration=0.8, action="close", hold=0.4)
    return wp1, wp2


class Task:
    """One tabletop task; subclasses lay out the scene, plan the keyframes and check the goal."""

    name: ClassVar[str]
    #: Roles of the objects laid out on the table.
    roles: ClassVar[tuple[str, ...]] = ("target", "distractor")

    def build(self, client: Any, look: Look, rng: np.random.Generator) -> Layout:
        raise NotImplementedError

    def plan(self, layout: Layout, *, obj: str = "target") -> Plan:
        raise NotImplementedError

    def check(self, client: Any, layout: Layout) -> GoalCheck:
        raise NotImplementedError


class PickCube(Task):
    """Pick the red cube up and hold it above the table."""

    name = "pick_cube"
    present = (0.40, 0.08, 0.26)

    def build(self, client: Any, look: Look, rng: np.random.Generator) -> Layout:
        starts = {
            "target": (*_jitter(rng, 0.50, -0.06, 0.03), _skewed_yaw(rng)),
            "distractor": (*_jitter(rng, 0.56, 0.15, 0.02), float(rng.uniform(-0.6, 0.6))),
        }
        bodies = {r: _cube(client, rng, look, (s[0], s[1]), s[2], r) for r, s in starts.items()}
        return Layout(bodies=bodies, starts=starts, size=look.cube_size)

    def plan(self, layout: Layout, *, obj: str = "target") -> Plan:
        x, y, yaw = layout.starts[obj]
        half = layout.size / 2
        wp1, wp2 = _grasp_keyframes(x, y, yaw, half)
        wp3 = Keyframe(3, (x, y, CARRY), wp2.yaw, duration=0.9)
        wp4 = Keyframe(4, self.present, HOME_YAW, duration=1.0)
        wp5 = Keyframe(5, (self.present[0], self.present[1], self.present[2] + 0.05), HOME_YAW, duration=0.6)
        return (wp1, wp2, wp3, wp4, wp5)

    def check(self, client: Any, layout: Layout) -> GoalCheck:
        position, _ = _pose(client, layout.bodies["target"])
        height = position[2] - TABLE_TOP - layout.size / 2
        return GoalCheck(passed=height > 0.1, values={"lift_m": height})


class PushCube(Task):
    """Push the red cube along the table into the green goal disc."""

    name = "push_cube"
    goal_radius = 0.04
    #: The cube's centre must end this close to the goal's centre.
    tolerance = 0.02
    #: Grasp-point height while pushing (fingertips just above the table).
    push_z = 0.018

    def build(self, client: Any, look: Look, rng: np.random.Generator) -> Layout:
        x, y = _jitter(rng, 0.42, -0.13, 0.02)
        # A diagonal push: the hand must turn about 60 degrees from its start to push square.
        goal = _jitter(rng, 0.54, 0.08, 0.015)
        # The cube sits roughly square to the push, as a pushing policy would be set up.
        heading = math.atan2(goal[1] - y, goal[0] - x)
        starts = {
            "target": (x, y, heading + float(rng.uniform(-0.12, 0.12))),
            "distractor": (*_jitter(rng, 0.61, -0.16, 0.015), float(rng.uniform(-0.6, 0.6))),
        }
        add_goal_marker(client, position=goal, radius=self.goal_radius, rgba=look.goal_rgba)
        bodies = {r: _cube(client, rng, look, (s[0], s[1]), s[2], r) for r, s in starts.items()}
        return Layout(bodies=bodies, starts=starts, size=look.cube_size, goal=goal)

    def plan(self, layout: Layout, *, obj: str = "target") -> Plan:
        x, y, _ = layout.starts[obj]
        target = layout.starts["target"]
        # The object is pushed by the goal's offset from the target (the target lands on the goal).
        gx, gy = x + layout.goal[0] - target[0], y + layout.goal[1] - target[1]
        reach = layout.size / 2 + 0.013  # grasp point to the pushed cube's centre, along the push
        heading = math.atan2(gy - y, gx - x)
        ux, uy = math.cos(heading), math.sin(heading)
        behind = layout.size / 2 + 0.045
        z = self.push_z
        mid = ((x + gx) / 2 - reach * ux, (y + gy) / 2 - reach * uy)
        end = (gx - reach * ux, gy - reach * uy)
        # The fingers close along the hand's y axis; yaw = heading puts their flat side forward.
        wp1 = Keyframe(1, (x - behind * ux, y - behind * uy, z + 0.1), heading, duration=1.0)
        wp2 = Keyframe(
            2, (x - behind * ux, y - behind * uy, z), heading, duration=0.8, action="close", hold=0.4
        )
        wp3 = Keyframe(3, (*mid, z), heading, duration=1.0)
        wp4 = Keyframe(4, (*end, z), heading, duration=1.0)
        wp5 = Keyframe(5, (end[0] - RETREAT, end[1] - 0.05 * uy, 0.2), heading, duration=0.7)
        return (wp1, wp2, wp3, wp4, wp5)

    def check(self, client: Any, layout: Layout) -> GoalCheck:
        position, orientation = _pose(client, layout.bodies["target"])
        distance = math.hypot(position[0] - layout.goal[0], position[1] - layout.goal[1])
        tilt = tilt_deg(orientation)
        passed = distance < self.tolerance and tilt < 15.0
        return GoalCheck(passed=passed, values={"goal_distance_m": distance, "tilt_deg": tilt})


class StackCube(Task):
    """Stack the red cube on the blue one."""

    name = "stack_cube"
    roles = ("target", "second", "distractor")

    def build(self, client: Any, look: Look, rng: np.random.Generator) -> Layout:
        starts = {
            "target": (*_jitter(rng, 0.50, -0.14, 0.02), _skewed_yaw(rng)),
            "second": (*_jitter(rng, 0.48, 0.12, 0.02), float(rng.uniform(-0.25, 0.25))),
            "distractor": (*_jitter(rng, 0.64, -0.02, 0.02), float(rng.uniform(-0.6, 0.6))),
        }
        bodies = {r: _cube(client, rng, look, (s[0], s[1]), s[2], r) for r, s in starts.items()}
        return Layout(bodies=bodies, starts=starts, size=look.cube_size)

    def plan(self, layout: Layout, *, obj: str = "target") -> Plan:
        x, y, yaw = layout.starts[obj]
        bx, by, byaw = layout.starts["second"]
        half = layout.size / 2
        wp1, wp2 = _grasp_keyframes(x, y, yaw, half)
        place_yaw = wrap_quarter(byaw)
        wp3 = Keyframe(3, (bx, by, layout.size + half + 0.08), place_yaw, duration=1.2)
        wp4 = Keyframe(
            4, (bx, by, layout.size + half + 0.004), place_yaw, duration=0.8, action="open", hold=0.3
        )
        wp5 = Keyframe(5, (bx - RETREAT, by, CARRY + 0.05), place_yaw, duration=0.7)
        return (wp1, wp2, wp3, wp4, wp5)

    def check(self, client: Any, layout: Layout) -> GoalCheck:
        top, orientation = _pose(client, layout.bodies["target"])
        base, _ = _pose(client, layout.bodies["second"])
        offset = math.hypot(top[0] - base[0], top[1] - base[1])
        rise = top[2] - base[2]
        tilt = tilt_deg(orientation)
        passed = offset < 0.35 * layout.size and abs(rise - layout.size) < 0.01 and tilt < 10.0
        return GoalCheck(passed=passed, values={"xy_offset_m": offset, "rise_m": rise, "tilt_deg": tilt})


class PutInTray(Task):
    """Put the red cube into the tray."""

    name = "put_in_tray"

    def build(self, client: Any, look: Look, rng: np.random.Generator) -> Layout:
        starts = {
            "target": (*_jitter(rng, 0.46, -0.14, 0.02), _skewed_yaw(rng)),
            "distractor": (*_jitter(rng, 0.62, -0.05, 0.02), float(rng.uniform(-0.6, 0.6))),
        }
        tray = _jitter(rng, 0.52, 0.16, 0.01)
        bodies = {r: _cube(client, rng, look, (s[0], s[1]), s[2], r) for r, s in starts.items()}
        bodies["tray"] = add_tray(client, position=tray, rgba=look.tray_rgba)
        return Layout(bodies=bodies, starts=starts, size=look.cube_size, goal=tray)

    def plan(self, layout: Layout, *, obj: str = "target") -> Plan:
        x, y, yaw = layout.starts[obj]
        tx, ty = layout.goal
        half = layout.size / 2
        wp1, wp2 = _grasp_keyframes(x, y, yaw, half)
        wp3 = Keyframe(3, (tx, ty, CARRY), HOME_YAW, duration=1.2)
        wp4 = Keyframe(
            4, (tx, ty, TRAY_THICK + half + 0.025), HOME_YAW, duration=0.8, action="open", hold=0.3
        )
        wp5 = Keyframe(5, (tx - RETREAT, ty, CARRY + 0.05), HOME_YAW, duration=0.7)
        return (wp1, wp2, wp3, wp4, wp5)

    def check(self, client: Any, layout: Layout) -> GoalCheck:
        position, _ = _pose(client, layout.bodies["target"])
        dx = abs(position[0] - layout.goal[0])
        dy = abs(position[1] - layout.goal[1])
        inside = max(dx, dy) < TRAY_INNER / 2
        low = position[2] - TABLE_TOP < TRAY_WALL + layout.size / 2
        return GoalCheck(
            passed=inside and low,
            values={"offset_x_m": dx, "offset_y_m": dy, "height_m": position[2] - TABLE_TOP},
        )


TASK_CLASSES: Final[dict[str, type[Task]]] = {
    cls.name: cls for cls in (PickCube, PushCube, StackCube, PutInTray)
}
TASKS: Final[tuple[str, ...]] = tuple(TASK_CLASSES)
