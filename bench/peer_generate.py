"""A FailGen-style set simulated in ManiSkill3, written as image-episode folders and a labels CSV.

Runs in the bench-only venv that `bench/setup_peer.sh` makes (mani-skill 3.0.x, numpy < 2, SAPIEN on
Mesa 25's lavapipe); it imports neither robofailring nor anything of the project's venv. The
measuring side is `bench/bench_peer.py`, which calls it and reads what it writes through the
library's own loaders. Written under `--out` (atomically: a staging folder renamed at the end):

- `episodes/<episode>/<view>/<n>.png`: one folder per episode, one per camera (`hand`: the Panda's
  hand camera, `base`: the task's sensor camera, `render`: the task's render camera);
- `episodes/<episode>/signals.npz`: the robot's own signals at each written frame (`SIGNALS`): joint
  positions (the arm's and the two fingers'), the arm's joint velocities, gripper width, the hand's (TCP) pose, the commanded joint-position action, the task's goal
  (PickCube's goal marker, PushCube's goal region, the cube StackCube stacks on) and the hand's offset
  from it;
- `labels.csv`: `episode, task, outcome, symbol, onset_frame, description` (robofailring's labels file);
- `runs.jsonl`: per episode the injected intent, the steps simulated and the environment's verdict;
- `signals.json`: each signal's kind and dimension names.

The Panda (`panda_wristcam`) follows a motion-planned script (mplib screw motions, as ManiSkill's
own motion-planning solutions do); one of FailGen's failure modes is injected at one waypoint
(paper §3, Appendix B). The outcome is the environment's own `evaluate()["success"]` at the end,
never the intent: a perturbed run the environment judges a success is a success, an unperturbed
run it judges failed is a failure with no type. The onset is the first written frame at or after
the step where the perturbed plan first departs from the nominal one. Each run is simulated once
without cameras (state observations), and only the frames written are rendered, from its states.
`--ood`: ManiSkill's own randomisation tools give each episode new lighting (ambient and
directional), colours (cubes, goal, table, floor) and camera poses (`noised_look_at`).
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import mani_skill.envs  # noqa: F401  (registers the tasks)
import numpy as np
import sapien
import torch
from mani_skill.envs.utils import randomization
from mani_skill.examples.motionplanning.base_motionplanner.utils import (
    compute_grasp_info_by_obb,
    get_actor_obb,
)
from mani_skill.examples.motionplanning.panda.motionplanner import PandaArmMotionPlanningSolver
from PIL import Image
from transforms3d.euler import euler2quat

TASKS = ("PickCube-v1", "StackCube-v1", "PushCube-v1")
#: Failure families each task allows, with the waypoint FailGen injects them at.
FAMILIES: dict[str, dict[str, int]] = {
    "PickCube-v1": {
        "grasp": 2,
        "slip": 3,
        "translation": 2,
        "rotation": 2,
        "no_rotation": 1,
        "wrong_sequence": 2,
    },
    "StackCube-v1": {
        "grasp": 2,
        "slip": 3,
        "translation": 2,
        "rotation": 2,
        "no_rotation": 1,
        "wrong_sequence": 2,
        "wrong_object": 1,
    },
    "PushCube-v1": {"translation": 3, "rotation": 3, "wrong_sequence": 3},
}
AXES = ("x", "y", "z")
VIEWS = ("hand", "base", "render")
SHIFT_M = 0.07  # a translation fault's offset (z: upwards, the table is below)
TURN_RAD = np.radians(45.0)  # a rotation fault's angle
HOLD_STEPS = 10  # steps held still after the script, before the environment's check
#: The signals written per frame: name -> (kind, dimension names), as bench_peer.py exports them.
SIGNALS: dict[str, tuple[str, tuple[str, ...]]] = {
    "joint_positions": ("state", (*(f"panda_joint{i}" for i in range(1, 8)), "finger_left", "finger_right")),
    "joint_velocities": ("state", tuple(f"panda_joint{i}" for i in range(1, 8))),
    "gripper_width": ("state", ("width",)),
    "ee_pose": ("state", ("x", "y", "z", "qw", "qx", "qy", "qz")),
    "ee_to_goal": ("state", ("dx", "dy", "dz")),
    "action": ("action", (*(f"panda_joint{i}" for i in range(1, 8)), "gripper")),
    "goal": ("other", ("x", "y", "z")),
}


@dataclass(frozen=True)
class Spec:
    task: str
    kind: str  # "success" or a failure family
    index: int  # episode number within (task, kind)
    seed: int  # the environment's reset seed


class Script:
    """One run of the motion-planned script, with the step its fault began to act at."""

    def __init__(self, env: gym.Env, family: str | None, axis: str, sign: float) -> None:
        self.env, self.family, self.axis, self.sign = env, family, axis, sign
        self.u: Any = env.unwrapped
        self.planner = PandaArmMotionPlanningSolver(
            env, debug=False, vis=False, base_pose=self.u.agent.robot.pose, visualize_target_grasp_pose=False,
            print_env_info=False,
        )  # fmt: skip
        self.onset_step: int | None = None

    def fault(self, family: str) -> bool:
        """Whether this run's fault is `family`; the first time it is asked and is, the onset is now."""
        if self.family != family:
            return False
        if self.onset_step is None:
            self.onset_step = self.planner.elapsed_steps
        return True

    def move(self, pose: sapien.Pose) -> None:
        self.planner.move_to_pose_with_screw(pose)

    def perturbed(self, pose: sapien.Pose) -> sapien.Pose:
        """`pose` with this run's translation or rotation fault, if it has one (the onset is now)."""
        if self.fault("translation"):
            offset = np.zeros(3)
            offset["xyz".index(self.axis)] = SHIFT_M * (1.0 if self.axis == "z" else self.sign)
            return sapien.Pose(pose.p + offset, pose.q)
        if self.fault("rotation"):
            angles = [0.0, 0.0, 0.0]
            angles["xyz".index(self.axis)] = TURN_RAD * self.sign
            return pose * sapien.Pose(q=euler2quat(*angles))
        return pose

    def grasp_pose(self, actor: Any) -> sapien.Pose:
        """A top-down grasp of `actor`, turned to its faces (no_rotation: the hand's own yaw, unturned)."""
        approaching = np.array([0.0, 0.0, -1.0])
        closing = self.u.agent.tcp.pose.to_transformation_matrix()[0, :3, 1].cpu().numpy()
        if not self.fault("no_rotation"):
            info = compute_grasp_info_by_obb(
                get_actor_obb(actor), approaching=approaching, target_closing=closing, depth=0.025
            )
            closing = info["closing"]
        closing = closing - approaching * (closing @ approaching)
        return self.u.agent.build_grasp_pose(approaching, closing / np.linalg.norm(closing), actor.pose.sp.p)

    def pick(self, actor: Any) -> sapien.Pose:
        """Reach (wp1) and grasp (wp2) `actor`; returns the grasp pose planned."""
        grasp = self.grasp_pose(actor)
        self.move(grasp * sapien.Pose([0, 0, -0.05]))
        if self.fault("wrong_sequence"):
            self.planner.close_gripper()  # closes before descending: the grasp comes too early
        self.move(self.perturbed(grasp))
        if not self.fault("grasp"):  # the hand arrives and does not close
            self.planner.close_gripper()
        return grasp

    def carry(self, start: sapien.Pose, goal: sapien.Pose) -> None:
        """Carry (wp3) from `start` to `goal`; slip: the hand opens half-way."""
        if self.family == "slip":
            self.move(sapien.Pose((start.p + goal.p) / 2 + [0, 0, 0.05], goal.q))
            self.fault("slip")
            self.planner.open_gripper()
        self.move(goal)

    def hold(self) -> None:
        self.planner.close_gripper(t=HOLD_STEPS, gripper_state=self.planner.gripper_state)


def pick_cube(script: Script) -> None:
    u = script.u
    grasp = script.pick(u.cube)
    script.carry(grasp, sapien.Pose(u.goal_site.pose.sp.p, grasp.q))


def stack_cube(script: Script) -> None:
    u = script.u
    held, under = (u.cubeB, u.cubeA) if script.fault("wrong_object") else (u.cubeA, u.cubeB)
    grasp = script.pick(held)
    lift = sapien.Pose([0, 0, 0.1]) * grasp
    script.move(lift)
    on_top = under.pose * sapien.Pose([0, 0, float(u.cube_half_size[2]) * 2])
    offset = (on_top.p - held.pose.p).cpu().numpy()[0]
    script.carry(lift, sapien.Pose(lift.p + offset, lift.q))
    script.planner.open_gripper()


def push_cube(script: Script) -> None:
    u = script.u
    script.planner.close_gripper()
    hand = u.agent.tcp.pose.sp.q
    goal = sapien.Pose(u.goal_region.pose.sp.p + np.array([-0.12, 0, 0]), hand)
    if not script.fault("wrong_sequence"):  # skips getting behind the cube: pushes from where it is
        behind = sapien.Pose(u.obj.pose.sp.p + np.array([-0.05, 0, 0]), hand)
        script.move(script.perturbed(behind))
    script.move(script.perturbed(goal))


SCRIPTS: dict[str, Callable[[Script], None]] = {
    "PickCube-v1": pick_cube,
    "StackCube-v1": stack_cube,
    "PushCube-v1": push_cube,
}


def ood_look(env: Any, rng: np.random.Generator) -> None:
    """New lighting (ambient tint, one directional light) and colours for the scene's actors."""
    scene = env.scene
    scene.set_ambient_light(rng.uniform(0.1, 0.6, 3).tolist())
    direction = [*rng.uniform(-1, 1, 2), -1.0]
    scene.add_directional_light(direction, rng.uniform(0.3, 1.2, 3).tolist())
    for name, actor in scene.actors.items():
        colour = [*rng.uniform(0.05, 1.0, 3).tolist(), 1.0]
        for obj in actor._objs:
            body = getattr(obj, "entity", obj).find_component_by_type(sapien.render.RenderBodyComponent)
            for shape in [] if body is None else body.render_shapes:
                for part in shape.parts:
                    if "table" in name or "ground" in name:
                        part.material.set_base_color_texture(None)
                    part.material.set_base_color(colour)


def noised(pose: Any, rng: np.random.Generator) -> sapien.Pose:
    """A camera pose near `pose`: its eye moved and its aim noised with ManiSkill's `noised_look_at`."""
    p, q = (np.asarray(v, dtype=np.float32).reshape(-1)[-n:] for v, n in ((pose.p, 3), (pose.q, 4)))
    forward = sapien.Pose(p, q).to_transformation_matrix()[:3, 0]
    eye = p + rng.uniform([-0.08, -0.08, -0.05], [0.08, 0.08, 0.08])
    torch.manual_seed(int(rng.integers(2**31)))
    out = randomization.camera.noised_look_at(
        torch.tensor(eye[None], dtype=torch.float32), p + 0.6 * forward, look_at_noise=0.04,
        view_axis_rot_noise=0.15,
    )  # fmt: skip
    return sapien.Pose(out.p[0].numpy(), out.q[0].numpy())


def make(task: str, size: int, *, cameras: bool, poses: tuple[Any, Any] | None = None) -> gym.Env:
    sensors: dict[str, Any] = {"width": size, "height": size}
    render: dict[str, Any] = {"width": size, "height": size, "shader_pack": "minimal"}
    if poses is not None:
        sensors["base_camera"] = {"pose": poses[0]}
        render["pose"] = poses[1]
    return gym.make(
        task, obs_mode="rgb" if cameras else "state", render_mode="rgb_array" if cameras else None,
        robot_uids="panda_wristcam", control_mode="pd_joint_pos", sim_backend="cpu", sensor_configs=sensors,
        human_render_camera_configs=render,
    )  # fmt: skip


class Generator:
    def __init__(self, size: int, frames: int, ood: bool) -> None:
        self.size, self.frames, self.ood = size, frames, ood
        self.sim: dict[str, gym.Env] = {}
        self.cameras: dict[str, gym.Env] = {}

    def render_env(self, spec: Spec, rng: np.random.Generator) -> gym.Env:
        if spec.task not in self.cameras:
            self.cameras[spec.task] = make(spec.task, self.size, cameras=True)
        if not self.ood:
            return self.cameras[spec.task]
        u: Any = self.cameras[spec.task].unwrapped
        base = next(c for c in u._default_sensor_configs if c.uid == "base_camera").pose
        human = u._default_human_render_camera_configs
        human = human[0] if isinstance(human, list) else human
        return make(spec.task, self.size, cameras=True, poses=(noised(base, rng), noised(human.pose, rng)))

    def run(self, spec: Spec, out: Path) -> dict[str, Any]:
        rng = np.random.default_rng([spec.seed, int(self.ood)])
        families = FAMILIES[spec.task]
        family = None if spec.kind == "success" else spec.kind
        axis = AXES[spec.index % 3] if family in ("translation", "rotation") else ""
        sign = 1.0 if spec.index // 3 % 2 == 0 else -1.0
        if spec.task not in self.sim:
            self.sim[spec.task] = make(spec.task, self.size, cameras=False)
        sim: Any = self.sim[spec.task]
        sim.reset(seed=spec.seed)
        states = [sim.unwrapped.get_state_dict()]
        actions: list[np.ndarray] = []  # actions[i] took states[i] to states[i + 1]
        step = sim.step

        def recording(action: Any) -> Any:
            result = step(action)
            states.append(sim.unwrapped.get_state_dict())
            actions.append(np.asarray(action, dtype=np.float64).reshape(-1))
            return result

        sim.step = recording
        script = Script(sim, family, axis, sign)
        try:
            SCRIPTS[spec.task](script)
            script.hold()
        finally:
            sim.step = step
        success = bool(sim.unwrapped.evaluate()["success"][0])
        picked = sorted({int(i) for i in np.linspace(0, len(states) - 1, self.frames).round()})
        onset = None
        if script.onset_step is not None:
            onset = next((n for n, i in enumerate(picked) if i >= script.onset_step), len(picked) - 1)
        symbol = ""
        if family is not None:
            symbol = f"{family}_{axis}" if axis else family
            symbol += "" if family == "wrong_object" else f"_wp{families[family]}"
        name = f"{spec.task.split('-')[0].lower()}-{spec.kind.replace('_', '')}-{spec.index:03d}"
        self.write(spec, states, actions, picked, out / "episodes" / name, rng)
        if success:
            label = {"outcome": "success", "symbol": "", "onset_frame": ""}
            said = f"{symbol or 'nothing'} injected; the environment's check passed"
        elif family is None:
            label = {"outcome": "failure", "symbol": "", "onset_frame": ""}
            said = "nothing injected; the environment's check failed (a planner failure, type not labelled)"
        else:
            label = {"outcome": "failure", "symbol": symbol, "onset_frame": str(onset)}
            said = f"{symbol} injected at step {script.onset_step}; the environment's check failed"
        return {
            "episode": name, "task": spec.task, **label, "description": said,
            "intent": symbol or "success", "env_success": success, "steps": len(states) - 1,
            "onset_step": script.onset_step, "spec": asdict(spec),
        }  # fmt: skip

    def write(
        self,
        spec: Spec,
        states: list[Any],
        actions: list[np.ndarray],
        picked: list[int],
        folder: Path,
        rng: np.random.Generator,
    ) -> None:
        env = self.render_env(spec, rng)
        u: Any = env.unwrapped
        env.reset(seed=spec.seed)
        if self.ood:
            ood_look(u, rng)
        for view in VIEWS:
            (folder / view).mkdir(parents=True, exist_ok=True)
        rows: dict[str, list[np.ndarray]] = {name: [] for name in SIGNALS}
        for n, index in enumerate(picked):
            u.set_state_dict(states[index])
            for name, values in signals_now(u, spec.task, actions, index).items():
                rows[name].append(values)
            sensors = u.get_obs()["sensor_data"]
            images = {
                "hand": sensors["hand_camera"]["rgb"],
                "base": sensors["base_camera"]["rgb"],
                "render": env.render(),
            }
            for view, image in images.items():
                Image.fromarray(image[0].cpu().numpy().astype(np.uint8)).save(folder / view / f"{n}.png")
        np.savez(folder / "signals.npz", **{name: np.stack(values) for name, values in rows.items()})
        if self.ood:
            env.close()


def _vector(value: Any) -> np.ndarray:
    """A batched tensor's first row (ManiSkill's CPU backend batches by one) as float64."""
    return np.asarray(value.cpu().numpy() if hasattr(value, "cpu") else value, dtype=np.float64).reshape(-1)


def signals_now(u: Any, task: str, actions: list[np.ndarray], index: int) -> dict[str, np.ndarray]:
    """The robot's signals in state `index`: what `SIGNALS` names (the action: the one that led here)."""
    qpos = _vector(u.agent.robot.get_qpos()[0])
    qvel = _vector(u.agent.robot.get_qvel()[0])
    tcp = u.agent.tcp.pose
    position, orientation = _vector(tcp.p[0]), _vector(tcp.q[0])
    goal_actor = {"PickCube-v1": "goal_site", "PushCube-v1": "goal_region", "StackCube-v1": "cubeB"}[task]
    goal = _vector(getattr(u, goal_actor).pose.p[0])
    action = actions[max(index - 1, 0)] if actions else np.zeros(8)
    return {
        "joint_positions": qpos[:9],
        "joint_velocities": qvel[:7],
        "gripper_width": qpos[7:9].sum(keepdims=True),
        "ee_pose": np.concatenate([position, orientation]),
        "ee_to_goal": position - goal,
        "action": action[:8],
        "goal": goal,
    }


def specs(args: argparse.Namespace) -> list[Spec]:
    out = []
    for t, task in enumerate(args.tasks):
        kinds = [("success", args.successes)] + [(f, args.episodes) for f in FAMILIES[task]]
        for k, (kind, count) in enumerate(kinds):
            for index in range(count):
                out.append(Spec(task, kind, index, args.seed + 10_000 * t + 1_000 * k + index))
    return out


def _work(job: tuple[list[Spec], Path, int, int, bool]) -> list[dict[str, Any]]:
    chunk, out, size, frames, ood = job
    generator = Generator(size, frames, ood)
    return [generator.run(spec, out) for spec in chunk]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--tasks", nargs="+", default=list(TASKS))
    parser.add_argument("--episodes", type=int, default=4, help="per task and failure family")
    parser.add_argument("--successes", type=int, default=16, help="unperturbed runs per task")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--size", type=int, default=96, help="image size (px)")
    parser.add_argument("--frames", type=int, default=28, help="frames written per episode")
    parser.add_argument("--ood", action="store_true")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    staging = args.out.with_name(args.out.name + ".partial")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    todo = specs(args)
    chunks = [
        (todo[w :: args.workers], staging, args.size, args.frames, args.ood) for w in range(args.workers)
    ]
    if args.workers > 1:
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
            results = [row for rows in pool.map(_work, chunks) for row in rows]
    else:
        results = _work(chunks[0])
    results.sort(key=lambda row: row["episode"])
    columns = ("episode", "task", "outcome", "symbol", "onset_frame", "description")
    with (staging / "labels.csv").open("w", newline="", encoding="utf-8") as file:
        writer = csv.DictWriter(file, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(results)
    with (staging / "runs.jsonl").open("w", encoding="utf-8") as file:
        file.writelines(json.dumps(row) + "\n" for row in results)
    signals = {name: {"kind": kind, "names": list(dims)} for name, (kind, dims) in SIGNALS.items()}
    (staging / "signals.json").write_text(json.dumps(signals, indent=1), encoding="utf-8")
    shutil.rmtree(args.out, ignore_errors=True)
    staging.rename(args.out)
    judged = sum(row["outcome"] == "success" for row in results)
    print(f"{args.out}: {len(results)} episodes, {judged} judged successes by the environment")


if __name__ == "__main__":
    main()
