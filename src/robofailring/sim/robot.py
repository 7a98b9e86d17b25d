"""The Franka Panda: loading, inverse kinematics, gripper and constraint-based grasping."""

from __future__ import annotations

import functools
import hashlib
import math
import tempfile
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.atomic import write_text_atomic
from robofailring.extras import needs_extra
from robofailring.sim.geometry import Pose, Quat, Vec3, invert, multiply, quat_matrix

with needs_extra("sim"):
    import pybullet_data

ARM_JOINTS: Final[tuple[int, ...]] = (0, 1, 2, 3, 4, 5, 6)
FINGER_JOINTS: Final[tuple[int, int]] = (9, 10)
HAND_LINK: Final[int] = 8
EE_LINK: Final[int] = 11  # panda_grasptarget: between the fingertips
HOME_JOINTS: Final[tuple[float, ...]] = (0.0, -0.35, 0.0, -2.3, 0.0, 1.95, math.pi / 4)
_ARM_FORCES: Final[tuple[float, ...]] = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
#: Half the finger opening when open (m); the Panda opens to 8 cm.
FINGER_OPEN: Final[float] = 0.04
#: Finger squeeze (N) and pad friction: together too weak to lift a 50 g cube by friction alone
#: (2 * 0.4 * 0.3 N < 0.49 N), so a grasp holds only through the rigid attachment made when the
#: geometric check passes (see `Panda.graspable`); the pads still push with friction.
_FINGER_FORCE: Final[float] = 0.3
_PAD_FRICTION: Final[float] = 0.4
#: Arm links drawn with their collision mesh (300 triangles each): their visual meshes hold ~94k
#: triangles, which the TinyRenderer transforms for every image (18 of the 21 ms of a 128-px render,
#: whatever its size). The hand and fingers, close to the wrist camera, keep their visual meshes.
LOW_POLY_LINKS: Final[tuple[str, ...]] = ("link1", "link2", "link3", "link4", "link5", "link6")


@functools.cache
def panda_urdf() -> str:
    """pybullet_data's Panda with the arm links' visual meshes replaced by their collision meshes.

    Written once per content into the temporary folder (mesh paths made absolute), so the package
    folder is never written to.
    """
    root = Path(pybullet_data.getDataPath()) / "franka_panda"
    text = (root / "panda.urdf").read_text(encoding="utf-8")
    for link in LOW_POLY_LINKS:
        text = text.replace(f"package://meshes/visual/{link}.obj", f"package://meshes/collision/{link}.obj")
    text = text.replace("package://meshes/", f"{(root / 'meshes').as_posix()}/")
    path = (
        Path(tempfile.gettempdir())
        / f"robofailring-panda-{hashlib.sha256(text.encode()).hexdigest()[:12]}.urdf"
    )
    if not path.is_file():
        write_text_atomic(path, text)
    return str(path)


class Panda:
    """A Panda arm in one pybullet client, driven by IK towards end-effector poses."""

    def __init__(self, client: Any) -> None:
        self.client = client
        self.body: int = client.loadURDF(
            panda_urdf(),
            basePosition=(0.0, 0.0, 0.0),
            useFixedBase=True,
            flags=client.URDF_ENABLE_CACHED_GRAPHICS_SHAPES,
        )
        joints = [client.getJointInfo(self.body, j) for j in range(client.getNumJoints(self.body))]
        movable = [info for info in joints if info[2] != client.JOINT_FIXED]
        self._lower = [float(info[8]) for info in movable]
        self._upper = [float(info[9]) for info in movable]
        self._ranges = [hi - lo for lo, hi in zip(self._lower, self._upper, strict=True)]
        self._rest = [*HOME_JOINTS, FINGER_OPEN, FINGER_OPEN]
        for joint, value in zip(ARM_JOINTS, HOME_JOINTS, strict=True):
            client.resetJointState(self.body, joint, value)
        for joint in FINGER_JOINTS:
            client.resetJointState(self.body, joint, FINGER_OPEN)
            client.changeDynamics(self.body, joint, lateralFriction=_PAD_FRICTION)
        self._arm_targets: list[float] = list(HOME_JOINTS)
        self._finger_target = FINGER_OPEN
        self.held: int | None = None
        self._constraint: int | None = None
        self.drive_joints(self._arm_targets)
        self.set_fingers(FINGER_OPEN)

    # -- poses ---------------------------------------------------------------------------------
    def link_pose(self, link: int) -> Pose:
        state = self.client.getLinkState(self.body, link, computeForwardKinematics=True)
        return Pose(tuple(state[4]), tuple(state[5]))

    def ee_pose(self) -> Pose:
        """The grasp point between the fingertips (world frame)."""
        return self.link_pose(EE_LINK)

    @property
    def finger_target(self) -> float:
        """Each finger's commanded opening (m): half the commanded gripper width."""
        return self._finger_target

    # -- commands ------------------------------------------------------------------------------
    def drive_joints(self, targets: list[float]) -> None:
        self.client.setJointMotorControlArray(
            self.body,
            list(ARM_JOINTS),
            self.client.POSITION_CONTROL,
            targetPositions=targets,
            forces=list(_ARM_FORCES),
            positionGains=[0.3] * len(ARM_JOINTS),
        )

    def drive_pose(self, position: Vec3, orientation: Quat) -> None:
        """Command the arm towards an end-effector pose (one IK solve, null space near home)."""
        solution = self.client.calculateInverseKinematics(
            self.body,
            EE_LINK,
            position,
            orientation,
            lowerLimits=self._lower,
            upperLimits=self._upper,
            jointRanges=self._ranges,
            restPoses=self._rest,
            maxNumIterations=30,
            residualThreshold=1e-4,
        )
        self._arm_targets = [float(v) for v in solution[: len(ARM_JOINTS)]]
        self.drive_joints(self._arm_targets)

    def set_fingers(self, half_width: float) -> None:
        self._finger_target = half_width
        self.client.setJointMotorControlArray(
            self.body,
            list(FINGER_JOINTS),
            self.client.POSITION_CONTROL,
            targetPositions=[half_width, half_width],
            forces=[_FINGER_FORCE, _FINGER_FORCE],
        )

    # -- grasping ------------------------------------------------------------------------------
    def close_on(self, body: int | None, *, half_size: float) -> None:
        """Close the gripper; if `body` is graspable now, attach it rigidly (a firm grasp)."""
        if body is None:
            self.set_fingers(0.0)
            return
        pose = self.ee_pose()
        obj_pos, obj_orn = self.client.getBasePositionAndOrientation(body)
        relative = multiply(invert(pose), Pose(tuple(obj_pos), tuple(obj_orn)))
        for finger in FINGER_JOINTS:
            self.client.setCollisionFilterPair(self.body, body, finger, -1, 0)
        self._constraint = self.client.createConstraint(
            self.body,
            EE_LINK,
            body,
            -1,
            self.client.JOINT_FIXED,
            (0.0, 0.0, 0.0),
            relative.position,
            (0.0, 0.0, 0.0),
            relative.orientation,
        )
        self.client.changeConstraint(self._constraint, maxForce=300.0)
        self.held = body
        self.set_fingers(half_size + 0.001)

    def open(self) -> None:
        """Open the gripper, dropping whatever it holds."""
        if self._constraint is not None:
            self.client.removeConstraint(self._constraint)
            self._constraint = None
        if self.held is not None:
            for finger in FINGER_JOINTS:
                self.client.setCollisionFilterPair(self.body, self.held, finger, -1, 1)
            self.held = None
        self.set_fingers(FINGER_OPEN)

    def graspable(self, body: int, *, half_size: float, max_angle_deg: float = 15.0) -> bool:
        """Whether `body` (a cube) sits between the open fingers, square to them, gripper upright.

        A cube grasped on its edges, off-centre or with a tilted hand would slip out of a real
        parallel gripper; the simulated grasp is rigid, so this check decides whether it forms.
        """
        pose = self.ee_pose()
        obj_pos, obj_orn = self.client.getBasePositionAndOrientation(body)
        rel = multiply(invert(pose), Pose(tuple(obj_pos), tuple(obj_orn)))
        dx, dy, dz = rel.position
        opening = FINGER_OPEN  # half the gap between the open fingers
        if abs(dy) > opening - half_size + 0.004 or abs(dx) > 0.6 * half_size or abs(dz) > half_size:
            return False
        hand = quat_matrix(pose.orientation)
        cosine = math.cos(math.radians(max_angle_deg))
        if float(-hand[2, 2]) < cosine:  # the fingers must point down
            return False
        closing = hand[:, 1]
        cube = quat_matrix(tuple(obj_orn))
        return float(np.max(np.abs(cube.T @ closing))) >= cosine
