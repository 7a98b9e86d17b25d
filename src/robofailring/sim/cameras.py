"""The three cameras (front, overhead, wrist) rendered with pybullet's CPU TinyRenderer."""

from __future__ import annotations

from typing import Any, Final

import numpy as np

from robofailring.sim.appearance import Look
from robofailring.sim.geometry import Pose, Vec3, multiply, rotate
from robofailring.sim.robot import EE_LINK, Panda

VIEWS: Final[tuple[str, ...]] = ("front", "overhead", "wrist")

#: Fixed cameras: eye, target, up vector, vertical field of view (degrees).
_FIXED: Final[dict[str, tuple[Vec3, Vec3, Vec3, float]]] = {
    "front": ((1.15, 0.0, 0.60), (0.32, 0.0, 0.21), (0.0, 0.0, 1.0), 56.0),
    "overhead": ((0.60, 0.02, 1.45), (0.52, 0.02, 0.0), (-1.0, 0.0, 0.0), 25.0),
}
#: The wrist camera in the grasp-point frame (z points along the fingers): eye and look-at point.
_WRIST_EYE: Final[Vec3] = (0.09, 0.0, -0.08)
_WRIST_AT: Final[Vec3] = (0.0, 0.0, 0.08)
_WRIST_FOV: Final[float] = 75.0


class CameraRig:
    """Renders RGB images of the three views for one scene look and image size."""

    def __init__(self, client: Any, look: Look, *, image_size: int) -> None:
        self.client = client
        self.look = look
        self.size = image_size
        self._fixed: dict[str, tuple[Any, Any]] = {}
        sx, sy, sz = look.camera_shift
        for view, (eye, target, up, fov) in _FIXED.items():
            scale = 0.5 if view == "overhead" else 1.0
            moved = (eye[0] + scale * sx, eye[1] + scale * sy, eye[2] + scale * sz)
            matrix = client.computeViewMatrix(moved, target, up)
            projection = client.computeProjectionMatrixFOV(fov, 1.0, 0.1, 4.0)
            self._fixed[view] = (matrix, projection)
        self._wrist_projection = client.computeProjectionMatrixFOV(_WRIST_FOV, 1.0, 0.01, 3.0)

    def _wrist(self, robot: Panda) -> Any:
        ee: Pose = robot.link_pose(EE_LINK)
        eye = multiply(ee, Pose(_WRIST_EYE, (0.0, 0.0, 0.0, 1.0))).position
        target = multiply(ee, Pose(_WRIST_AT, (0.0, 0.0, 0.0, 1.0))).position
        up = rotate(ee.orientation, (1.0, 0.0, 0.0))
        return self.client.computeViewMatrix(eye, target, up)

    def _render(self, view_matrix: Any, projection: Any) -> np.ndarray:
        look = self.look
        _, _, rgba, _, _ = self.client.getCameraImage(
            self.size,
            self.size,
            viewMatrix=view_matrix,
            projectionMatrix=projection,
            lightDirection=look.light_direction,
            lightColor=look.light_color,
            lightAmbientCoeff=look.ambient,
            lightDiffuseCoeff=look.diffuse,
            lightSpecularCoeff=look.specular,
            shadow=0,
            renderer=self.client.ER_TINY_RENDERER,
            flags=self.client.ER_NO_SEGMENTATION_MASK,
        )
        image = np.asarray(rgba, dtype=np.uint8).reshape(self.size, self.size, 4)
        return np.ascontiguousarray(image[:, :, :3])

    def capture(self, robot: Panda) -> dict[str, np.ndarray]:
        """One RGB uint8 image per view, (size, size, 3)."""
        images = {view: self._render(*self._fixed[view]) for view in ("front", "overhead")}
        images["wrist"] = self._render(self._wrist(robot), self._wrist_projection)
        return images
