"""Scene building blocks: a physics client, the table, cubes, a tray and a goal marker."""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator
from typing import Any

from robofailring.extras import needs_extra
from robofailring.sim.appearance import RGBA, Look
from robofailring.sim.geometry import Vec3, axis_angle


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence what the pybullet C library prints on import ("pybullet build time: …" on stderr,
    before any `error:` line) and on connect ("argv[0]=" on stdout, which breaks progress bars)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    try:
        with open(os.devnull, "wb") as devnull:
            for fd in saved:
                os.dup2(devnull.fileno(), fd)
        yield
    finally:
        with contextlib.suppress(OSError, AttributeError):  # C's stdio buffers go to /dev/null too
            ctypes.CDLL(None).fflush(None)
        for fd, kept in saved.items():
            os.dup2(kept, fd)
            os.close(kept)


with needs_extra("sim"), _quiet_stdout():
    import pybullet
    import pybullet_data
    from pybullet_utils.bullet_client import BulletClient

PHYSICS_HZ = 240
TABLE_TOP = 0.0
#: Inner side of the tray (m), its wall height and thickness.
TRAY_INNER = 0.17
TRAY_WALL = 0.045
TRAY_THICK = 0.01


def connect() -> Any:
    """A fresh headless pybullet client (DIRECT mode, deterministic contact ordering)."""
    with _quiet_stdout():
        client = BulletClient(connection_mode=pybullet.DIRECT)
    client.setAdditionalSearchPath(pybullet_data.getDataPath())
    reset(client)
    return client


def reset(client: Any) -> None:
    """Empty the world and set gravity and the fixed physics step."""
    client.resetSimulation()
    client.setPhysicsEngineParameter(
        fixedTimeStep=1.0 / PHYSICS_HZ, numSolverIterations=60, deterministicOverlappingPairs=1
    )
    client.setGravity(0.0, 0.0, -9.81)


def add_table(client: Any, look: Look) -> int:
    """A static table whose top is the plane z = 0, with the robot's base at the origin."""
    half = (0.62, 0.62, 0.025)
    center = (0.42, 0.0, TABLE_TOP - half[2])
    collision = client.createCollisionShape(client.GEOM_BOX, halfExtents=half)
    visual = client.createVisualShape(client.GEOM_BOX, halfExtents=half, rgbaColor=look.table_rgba)
    body: int = client.createMultiBody(0.0, collision, visual, center)
    client.changeDynamics(body, -1, lateralFriction=0.5)
    floor = client.createVisualShape(client.GEOM_BOX, halfExtents=(3.0, 3.0, 0.01), rgbaColor=_floor(look))
    client.createMultiBody(0.0, -1, floor, (0.0, 0.0, -0.75))
    return body


def _floor(look: Look) -> RGBA:
    r, g, b, _ = look.table_rgba
    return (0.45 * r, 0.45 * g, 0.45 * b, 1.0)


def add_cube(client: Any, *, size: float, position: tuple[float, float], yaw: float, rgba: RGBA) -> int:
    """A 50 g cube resting on the table."""
    half = (size / 2, size / 2, size / 2)
    collision = client.createCollisionShape(client.GEOM_BOX, halfExtents=half)
    visual = client.createVisualShape(client.GEOM_BOX, halfExtents=half, rgbaColor=rgba)
    body: int = client.createMultiBody(
        0.05,
        collision,
        visual,
        (position[0], position[1], TABLE_TOP + size / 2),
        axis_angle("z", yaw),
    )
    client.changeDynamics(body, -1, lateralFriction=0.6, spinningFriction=0.001, rollingFriction=0.0)
    return body


def add_tray(client: Any, *, position: tuple[float, float], rgba: RGBA) -> int:
    """A static open box: a floor and four walls, inner side TRAY_INNER."""
    outer = TRAY_INNER / 2 + TRAY_THICK
    wall_z = TRAY_WALL / 2
    parts: list[tuple[Vec3, Vec3]] = [
        ((outer, outer, TRAY_THICK / 2), (0.0, 0.0, TRAY_THICK / 2)),
        ((TRAY_THICK / 2, outer, wall_z), (outer - TRAY_THICK / 2, 0.0, wall_z)),
        ((TRAY_THICK / 2, outer, wall_z), (-outer + TRAY_THICK / 2, 0.0, wall_z)),
        ((outer, TRAY_THICK / 2, wall_z), (0.0, outer - TRAY_THICK / 2, wall_z)),
        ((outer, TRAY_THICK / 2, wall_z), (0.0, -outer + TRAY_THICK / 2, wall_z)),
    ]
    halves = [list(h) for h, _ in parts]
    offsets = [list(o) for _, o in parts]
    types = [client.GEOM_BOX] * len(parts)
    collision = client.createCollisionShapeArray(types, halfExtents=halves, collisionFramePositions=offsets)
    visual = client.createVisualShapeArray(
        types, halfExtents=halves, visualFramePositions=offsets, rgbaColors=[list(rgba)] * len(parts)
    )
    body: int = client.createMultiBody(0.0, collision, visual, (position[0], position[1], TABLE_TOP))
    return body


def add_goal_marker(client: Any, *, position: tuple[float, float], radius: float, rgba: RGBA) -> int:
    """A flat disc painted on the table (visual only)."""
    visual = client.createVisualShape(client.GEOM_CYLINDER, radius=radius, length=0.002, rgbaColor=rgba)
    body: int = client.createMultiBody(0.0, -1, visual, (position[0], position[1], TABLE_TOP + 0.001))
    return body
