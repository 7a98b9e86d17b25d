"""Small rigid-body maths in numpy (quaternions are pybullet's x, y, z, w order)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
IDENTITY: Quat = (0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Pose:
    """A position and an orientation in the world (or relative) frame."""

    position: Vec3
    orientation: Quat


def quat_multiply(a: Quat, b: Quat) -> Quat:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def quat_conjugate(q: Quat) -> Quat:
    return (-q[0], -q[1], -q[2], q[3])


def quat_matrix(q: Quat) -> np.ndarray:
    """3x3 rotation matrix of a unit quaternion."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def rotate(q: Quat, v: Vec3) -> Vec3:
    out = quat_matrix(q) @ np.asarray(v, dtype=float)
    return (float(out[0]), float(out[1]), float(out[2]))


def axis_angle(axis: str, angle: float) -> Quat:
    """The rotation by `angle` radians about the world axis named x, y or z."""
    half = angle / 2.0
    s = math.sin(half)
    vector = {"x": (s, 0.0, 0.0), "y": (0.0, s, 0.0), "z": (0.0, 0.0, s)}[axis]
    return (vector[0], vector[1], vector[2], math.cos(half))


def top_down(yaw: float) -> Quat:
    """A gripper pointing straight down, its fingers closing along the world y axis turned by `yaw`."""
    return quat_multiply(axis_angle("z", yaw), axis_angle("x", math.pi))


def multiply(a: Pose, b: Pose) -> Pose:
    """Compose poses: b expressed in a's frame, returned in a's parent frame."""
    moved = rotate(a.orientation, b.position)
    position = (a.position[0] + moved[0], a.position[1] + moved[1], a.position[2] + moved[2])
    return Pose(position, quat_multiply(a.orientation, b.orientation))


def invert(a: Pose) -> Pose:
    conj = quat_conjugate(a.orientation)
    back = rotate(conj, a.position)
    return Pose((-back[0], -back[1], -back[2]), conj)


def slerp(a: Quat, b: Quat, s: float) -> Quat:
    """Spherical interpolation along the shorter arc."""
    qa = np.asarray(a, dtype=float)
    qb = np.asarray(b, dtype=float)
    dot = float(qa @ qb)
    if dot < 0.0:
        qb, dot = -qb, -dot
    if dot > 0.9995:
        out = qa + s * (qb - qa)
    else:
        theta = math.acos(min(dot, 1.0))
        out = (math.sin((1 - s) * theta) * qa + math.sin(s * theta) * qb) / math.sin(theta)
    out /= np.linalg.norm(out)
    return (float(out[0]), float(out[1]), float(out[2]), float(out[3]))


def tilt_deg(q: Quat) -> float:
    """Angle between a body's z axis and the world z axis, in degrees."""
    return math.degrees(math.acos(max(-1.0, min(1.0, float(quat_matrix(q)[2, 2])))))


def yaw_of(q: Quat) -> float:
    """Heading of a body's x axis in the world xy plane (radians)."""
    m = quat_matrix(q)
    return math.atan2(float(m[1, 0]), float(m[0, 0]))


def wrap_quarter(angle: float) -> float:
    """An angle folded into [-pi/4, pi/4): a cube looks the same every quarter turn."""
    return (angle + math.pi / 4) % (math.pi / 2) - math.pi / 4
