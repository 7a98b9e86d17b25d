"""The simulator's Panda: the arm links drawn with their collision meshes, the hand and fingers as they are."""

from __future__ import annotations

import re
from pathlib import Path

import pybullet_data

from robofailring.sim.robot import LOW_POLY_LINKS, panda_urdf


def _visual_meshes(urdf: str) -> list[str]:
    return re.findall(r"<visual>.*?<mesh filename=\"([^\"]+)\"", urdf, flags=re.DOTALL)


def test_the_arm_is_drawn_with_collision_meshes_and_the_hand_keeps_its_own() -> None:
    package = Path(pybullet_data.getDataPath()) / "franka_panda"
    original = (package / "panda.urdf").read_text(encoding="utf-8")
    written = Path(panda_urdf())
    ours = written.read_text(encoding="utf-8")
    meshes = _visual_meshes(ours)
    assert len(meshes) == len(_visual_meshes(original)) and all(Path(mesh).is_file() for mesh in meshes)
    by_name = {Path(mesh).stem: Path(mesh).parent.name for mesh in meshes}
    assert {link: by_name[link] for link in LOW_POLY_LINKS} == dict.fromkeys(LOW_POLY_LINKS, "collision")
    assert by_name["hand"] == "visual" and by_name["finger"] == "visual"
    # everything but the mesh paths is pybullet_data's file, which stays as it was
    assert re.sub(r'filename="[^"]+"', "", ours) == re.sub(r'filename="[^"]+"', "", original)
    assert written.parent != package and panda_urdf() == str(written)
