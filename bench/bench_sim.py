"""Where a simulated episode's time goes: physics steps against rendering, and the low-poly arm's gain.

One run times, on the same scene and cameras, the three views rendered with pybullet_data's Panda
(visual meshes, ~100k triangles) and with the simulator's Panda (`robot.panda_urdf`: the arm links'
collision meshes), and one episode's physics steps, then prints the ratios side by side:

    .venv/bin/python -m bench.bench_sim [--size 128] [--repeat 30]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench._timing import median_ms, print_machine
from robofailring.sim.appearance import make_look
from robofailring.sim.cameras import CameraRig
from robofailring.sim.episode import frame_steps, run_episode
from robofailring.sim.geometry import Pose
from robofailring.sim.robot import panda_urdf
from robofailring.sim.scene import add_table, connect


def render_ms(urdf: str, *, size: int, repeat: int) -> float:
    """Median time of one capture of the three views of a table and a Panda loaded from `urdf`."""
    client = connect()
    try:
        look = make_look("in", rng=np.random.default_rng(0))
        add_table(client, look)
        body = client.loadURDF(urdf, useFixedBase=True, flags=client.URDF_ENABLE_CACHED_GRAPHICS_SHAPES)
        rig = CameraRig(client, look, image_size=size)

        class Posed:  # the one robot method the rig asks: the wrist camera's link pose
            def link_pose(self, link: int) -> Pose:
                state = client.getLinkState(body, link, computeForwardKinematics=True)
                return Pose(tuple(state[4]), tuple(state[5]))

        return median_ms(lambda: rig.capture(Posed()), repeat)  # type: ignore[arg-type]
    finally:
        client.disconnect()


def episode_split(*, size: int, frames: int) -> tuple[float, float]:
    """Seconds one success episode spends in physics steps and in rendering."""
    physics = render = 0.0
    with run_episode("pick_cube", "success", seed=0, image_size=size, frames=frames) as run:
        controller, cameras, robot = run._controller, run._cameras, run._robot
        for step in frame_steps(frames):
            start = time.perf_counter()
            while controller.step_index < step:
                controller.step()
            middle = time.perf_counter()
            cameras.capture(robot)
            physics += middle - start
            render += time.perf_counter() - middle
    return physics, render


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128, help="image side (px)")
    parser.add_argument("--repeat", type=int, default=30, help="captures timed per arm")
    parser.add_argument("--frames", type=int, default=40, help="frames of the timed episode")
    args = parser.parse_args()
    print_machine()
    visual = render_ms("franka_panda/panda.urdf", size=args.size, repeat=args.repeat)
    low = render_ms(panda_urdf(), size=args.size, repeat=args.repeat)
    physics, render = episode_split(size=args.size, frames=args.frames)
    print(f"three views at {args.size} px: visual-mesh arm {visual:.1f} ms, low-poly arm {low:.1f} ms")
    print(f"render speed-up: {visual / low:.2f}x")
    print(
        f"one {args.frames}-frame episode (low-poly arm): physics {physics:.2f} s, rendering {render:.2f} s "
        f"({render / (physics + render):.0%} of the two)"
    )


if __name__ == "__main__":
    main()
