"""FailGen-style failure injection: perturb one waypoint of a nominal keyframe plan."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Final

import numpy as np

from robofailring.sim.geometry import Quat, axis_angle, quat_multiply, rotate
from robofailring.sim.plan import WAYPOINTS, Keyframe, Plan
from robofailring.sim.tasks import HOME_YAW

#: The seven failure-mode families (paper §4.1 / AHA FailGen).
FAILURE_FAMILIES: Final[tuple[str, ...]] = (
    "grasp",
    "slip",
    "translation",
    "rotation",
    "no_rotation",
    "wrong_sequence",
    "wrong_object",
)
AXES: Final[tuple[str, ...]] = ("x", "y", "z")
_AXIAL: Final[frozenset[str]] = frozenset({"translation", "rotation"})
#: Every concrete failure mode (axial families spelled out per axis).
FAILURE_MODES: Final[tuple[str, ...]] = tuple(
    f"{family}_{axis}" if family in _AXIAL else family
    for family in FAILURE_FAMILIES
    for axis in (AXES if family in _AXIAL else ("",))
)
SUCCESS: Final[str] = "success"
#: Episode kinds a dataset can ask for: a family, a concrete mode, or success.
KINDS: Final[tuple[str, ...]] = (*FAILURE_FAMILIES, SUCCESS)

TRANSLATION_M: Final[float] = 0.07
#: Distance from the Panda's wrist flange to the grasp point between the fingertips (m).
WRIST_TO_TIP: Final[float] = 0.105
ROTATION_RAD: Final[float] = math.radians(45.0)
TILT_RAD: Final[float] = math.radians(40.0)

_GRASP_TASK_WAYPOINTS: Final[dict[str, tuple[int, ...]]] = {
    "grasp": (2,),
    "slip": (3,),
    "translation_x": (2,),
    "translation_y": (2,),
    "translation_z": (2,),
    "rotation_x": (2,),
    "rotation_y": (2,),
    "rotation_z": (2,),
    "no_rotation": (1,),
    "wrong_sequence": (2,),
}
#: Waypoints where each mode is injected, per task: where it makes the task fail.
WAYPOINT_CHOICES: Final[dict[str, dict[str, tuple[int, ...]]]] = {
    "pick_cube": {**_GRASP_TASK_WAYPOINTS, "slip": (3, 4)},
    "stack_cube": {
        **_GRASP_TASK_WAYPOINTS,
        "translation_x": (2, 4),
        "translation_y": (2, 4),
        "rotation_x": (2, 4),
        "rotation_y": (2, 4),
    },
    "put_in_tray": dict(_GRASP_TASK_WAYPOINTS),
    "push_cube": {
        "grasp": (2,),
        "slip": (3, 4),
        "translation_x": (3, 4),
        "translation_y": (4,),
        "translation_z": (4,),
        "rotation_x": (4,),
        "rotation_y": (3,),
        "rotation_z": (3,),
        "no_rotation": (1,),
        "wrong_sequence": (3,),
    },
}


@dataclass(frozen=True)
class Perturbation:
    """One injected failure: the concrete mode, the waypoint and the signed magnitude."""

    mode: str
    waypoint: int | None
    sign: float = 1.0

    @property
    def family(self) -> str:
        return self.mode[:-2] if self.mode[-2:] in ("_x", "_y", "_z") else self.mode

    @property
    def axis(self) -> str | None:
        return self.mode[-1] if self.family in _AXIAL else None

    @property
    def symbol(self) -> str:
        """The FailGen label, e.g. ``translation_z_wp2`` or ``wrong_object``."""
        return self.mode if self.waypoint is None else f"{self.mode}_wp{self.waypoint}"


def resolve_mode(kind: str, rng: np.random.Generator) -> str:
    """A concrete mode for an episode kind: axial families get an axis drawn from `rng`."""
    if kind == SUCCESS or kind in FAILURE_MODES:
        return kind
    if kind in _AXIAL:
        return f"{kind}_{AXES[int(rng.integers(len(AXES)))]}"
    raise ValueError(f"unknown episode kind {kind!r}; expected one of {[*KINDS, *FAILURE_MODES]}")


def choose(
    task: str, mode: str, rng: np.random.Generator, *, waypoint: int | None = None
) -> Perturbation | None:
    """The perturbation of one episode (None for success); the waypoint is drawn unless given."""
    if mode == SUCCESS:
        return None
    if mode == "wrong_object":
        return Perturbation(mode, None)
    choices = WAYPOINT_CHOICES[task][mode]
    drawn = choices[int(rng.integers(len(choices)))]
    lowest = 2 if mode == "wrong_sequence" else 1  # a wrong sequence swaps wp<k> with wp<k-1>
    if waypoint is not None and not lowest <= waypoint <= len(WAYPOINTS):
        raise ValueError(
            f"{mode} cannot be injected at waypoint {waypoint}; expected {lowest}..{len(WAYPOINTS)}"
        )
    sign = float(rng.choice([-1.0, 1.0]))
    if mode == "translation_z":
        sign = 1.0  # downwards would drive the hand into the table
    return Perturbation(mode, waypoint if waypoint is not None else drawn, sign)


def apply(plan: Plan, perturbation: Perturbation | None) -> Plan:
    """The plan with the perturbation injected at waypoint k (wrong_object is applied when planning).

    - grasp: the gripper does not close at wp k;
    - slip: the grasp opens half-way through the motion to wp k;
    - translation_<axis>: wp k's position is offset by TRANSLATION_M along the world axis (up for z);
    - rotation_<axis>: wp k's hand is turned about the world axis (ROTATION_RAD about z, TILT_RAD
      about x or y), pivoting at the wrist flange;
    - no_rotation: the turn of the hand that wp k introduces is skipped (kept off from wp k on);
    - wrong_sequence: wp k's pose is visited in wp k-1's slot and vice versa, gripper actions stay
      in their slots (e.g. the gripper closes above the cube, then the hand goes down).
    """
    if perturbation is None or perturbation.waypoint is None:
        return plan
    frames = list(plan)
    k = perturbation.waypoint - 1
    family, axis = perturbation.family, perturbation.axis
    if family == "grasp":
        frames[k] = replace(frames[k], action=None)
    elif family == "slip":
        frames[k] = replace(frames[k], release_at=0.5)
    elif family == "translation":
        assert axis is not None
        delta = perturbation.sign * TRANSLATION_M
        frames[k] = frames[k].moved(**{f"d{axis}": delta})
    elif family == "rotation":
        assert axis is not None
        angle = perturbation.sign * (ROTATION_RAD if axis == "z" else TILT_RAD)
        frames[k] = _turn_about_wrist(frames[k], axis_angle(axis, angle))
    elif family == "no_rotation":
        previous = frames[k - 1].yaw if k > 0 else HOME_YAW
        skipped = frames[k].yaw - previous
        frames[k:] = [replace(f, yaw=f.yaw - skipped) for f in frames[k:]]
    elif family == "wrong_sequence":
        frames[k - 1], frames[k] = _swap_poses(frames[k - 1], frames[k])
    return tuple(frames)


def onset_time(nominal: Plan, perturbed: Plan) -> float | None:
    """When (s) the perturbed plan first commands something the nominal one does not, None if never.

    At the first keyframe that differs: a changed pose or timing deviates as its motion starts, a
    slip when the grasp opens, a skipped gripper action when the keyframe is reached. Every
    perturbation keeps the slots' durations, so both plans share their timeline up to there."""
    start = 0.0
    for before, after in zip(nominal, perturbed, strict=True):
        if before != after:
            pose_or_timing = replace(after, action=before.action, release_at=before.release_at) != before
            moments = [start] if pose_or_timing else []
            if after.release_at != before.release_at:
                moments.append(start + (after.release_at or before.release_at or 0.0) * before.duration)
            if after.action != before.action:
                moments.append(start + before.duration)
            return min(moments)
        start += before.duration + before.hold
    return None


def _turn_about_wrist(keyframe: Keyframe, turn: Quat) -> Keyframe:
    """The keyframe's hand turned by the world-frame rotation `turn` about the wrist flange.

    A wrong wrist orientation swings the fingertips (the grasp point, WRIST_TO_TIP below the
    flange) around the flange, as an error in the arm's last joints would.
    """
    before = keyframe.orientation
    turned = replace(keyframe, extra=quat_multiply(turn, keyframe.extra))
    reach = (0.0, 0.0, WRIST_TO_TIP)
    old, new = rotate(before, reach), rotate(turned.orientation, reach)
    return turned.moved(new[0] - old[0], new[1] - old[1], new[2] - old[2])


def _swap_poses(a: Keyframe, b: Keyframe) -> tuple[Keyframe, Keyframe]:
    """Waypoint b is visited in a's slot and vice versa; gripper actions keep their slots."""
    first = replace(a, position=b.position, yaw=b.yaw, extra=b.extra)
    second = replace(b, position=a.position, yaw=a.yaw, extra=a.extra)
    return first, second
