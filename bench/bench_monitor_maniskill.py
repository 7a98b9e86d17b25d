"""A real third-party env under the rollout monitor (issue 52, item 5): ManiSkill3's PickCube-v1 in the bench venv
that `bench/setup_peer.sh` makes, judged by a memory of ManiSkill3 runs, its rollout summary printed.

Run (in the bench venv; the project's core dependencies beside it in a folder of their own, numpy pinned to the
venv's own so the peer venv's torch and mani_skill keep theirs, and the peer venv is left as setup_peer.sh made it):

    ~/.cache/robofailring/peer-env/venv/bin/python -m pip install --target ~/.cache/robofailring/monitor-deps \\
        "numpy==$(~/.cache/robofailring/peer-env/venv/bin/python -c 'import numpy; print(numpy.__version__)')" \\
        faiss-cpu opencv-python-headless pyyaml typer tqdm
    source ~/.cache/robofailring/peer-env/env.sh
    PYTHONPATH=src:.:$HOME/.cache/robofailring/monitor-deps ~/.cache/robofailring/peer-env/venv/bin/python \\
        bench/bench_monitor_maniskill.py --memory MEMORY [--episodes 16] [--policy scripted]

MEMORY is a memory built (in the project's venv, `robofailring build-memory`) from ManiSkill3 PickCube-v1 runs
with the same cameras and image size: bench_peer.py's set (docs/bench_peer.md) with its views renamed to the
env's sensors (`--views hand=hand_camera,base=base_camera`), as docs/rollouts.md ("Measured on ManiSkill3") does.

The env is the peer set's: the Panda with its wrist camera (`panda_wristcam`), joint-position control, the CPU
simulator. `--policy scripted` (the default) is peer_generate.py's motion-planned script; `--faults` cycles
through what it does per episode (`none`: the nominal script; a FailGen family: that fault injected), so the
rollouts hold successes and failures. `random` (ManiSkill's action sampler) and `zero` fail every episode. The
episode's outcome is ManiSkill's own `success`: the env ends the episode when it is reached (`terminated`); a
script that finishes without it is cut at its last step (`truncated`), judged a failure by the env. The seeds
start at `--seed` (100000: clear of the peer set's, so no rollout is an episode of the memory).

`--state recorded` gives the robot's state as the set's `lerobot-recorded` names it, for a memory with signals
built from it. Such a memory must hold runs at the env's step rate. The peer set keeps 28 frames of a run. Its
signal vectors' frame index and action lags (in frames) then miss what the monitor sees at every step: a memory
built from it (`--signals observation.state:gripper_width.*,action:gripper --signal-features none`) alarmed on
every run at frame 21 (docs/rollouts.md, "Measured on ManiSkill3").
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from bench._timing import print_machine

#: What the scripted policy does in turn, episode after episode: the nominal script, then a fault.
DEFAULT_FAULTS = "none,grasp,none,slip,none,translation,none,wrong_sequence"


class EpisodeOver(Exception):
    """The env ended the episode (success reached, or cut) while the script was still stepping."""


def stepper(gym: Any) -> Any:
    """A wrapper the motion planner steps: each step goes through the monitor; `cut()` makes the next step the
    episode's last (truncated); a step that ends the episode raises `EpisodeOver` to stop the script."""

    class Cut(gym.Wrapper):
        """Under the monitor: reports `truncated` at the step after `cut()`."""

        def __init__(self, env: Any) -> None:
            super().__init__(env)
            self.cutting = False

        def reset(self, **kwargs: Any) -> Any:
            self.cutting = False
            return self.env.reset(**kwargs)

        def step(self, action: Any) -> Any:
            observation, reward, terminated, truncated, info = self.env.step(action)
            return observation, reward, terminated, truncated or self.cutting, info

    class Stepper(gym.Wrapper):
        """Over the monitor: what the planner steps."""

        def step(self, action: Any) -> Any:
            result = self.env.step(action)
            if bool(result[2]) or bool(result[3]):
                raise EpisodeOver
            return result

    return Cut, Stepper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--memory", type=Path, required=True, help="a memory of ManiSkill3 PickCube-v1 runs")
    parser.add_argument("--env", default="PickCube-v1")
    parser.add_argument("--task", default=None, help="the memory's task (default: the env id)")
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--max-steps", type=int, default=300, help="the env's time limit per episode")
    parser.add_argument("--image-size", type=int, default=64, help="the cameras' size (the memory's)")
    parser.add_argument("--policy", choices=("scripted", "random", "zero"), default="scripted")
    parser.add_argument("--faults", default=DEFAULT_FAULTS, help="the scripted policy's faults, in turn")
    parser.add_argument("--seed", type=int, default=100_000, help="the first episode's reset seed")
    parser.add_argument(
        "--state",
        choices=("maniskill", "recorded"),
        default="maniskill",
        help="the signals: ManiSkill's own (`agent/*`, `extra/*`, the `maniskill` adapter), or the robot's state "
        "named as the peer set's LeRobot dataset records it (`observation.state`, `action`)",
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="where the rollouts go (default: a temporary folder)"
    )
    args = parser.parse_args()
    print_machine(libraries=("mani_skill", "gymnasium"))

    import gymnasium as gym
    import mani_skill.envs  # noqa: F401  (registers the envs)
    import numpy as np

    from robofailring import RolloutMonitor, open_detector

    Cut, Stepper = stepper(gym)
    size = {"width": args.image_size, "height": args.image_size}
    maniskill = gym.make(
        args.env, obs_mode="rgb", num_envs=1, max_episode_steps=args.max_steps, robot_uids="panda_wristcam",
        control_mode="pd_joint_pos", sim_backend="cpu", sensor_configs=size,
    )  # fmt: skip
    env = Cut(maniskill)
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-monitor-maniskill-"))
    monitored = RolloutMonitor(
        env,
        open_detector(args.memory),
        out=out,
        adapter=recorded_state_adapter() if args.state == "recorded" else "maniskill",
        task=args.task or args.env,
    )
    faults = [fault.strip() for fault in args.faults.split(",") if fault.strip()]
    steps: list[float] = []
    ran: list[str] = []
    with monitored:
        for episode in range(args.episodes):
            monitored.reset(seed=args.seed + episode)
            if args.policy == "scripted":
                ran.append(run_script(monitored, env, Stepper, faults, episode, args.env, steps))
                continue
            while True:
                action = (
                    monitored.action_space.sample()
                    if args.policy == "random"
                    else np.zeros(monitored.action_space.shape)
                )
                start = time.perf_counter()
                _, _, terminated, truncated, _ = monitored.step(action)
                steps.append(time.perf_counter() - start)
                if bool(np.any(terminated)) or bool(np.any(truncated)):
                    break
    what = f"{args.policy} policy" + (
        f", faults in turn: {', '.join(faults)}" if args.policy == "scripted" else ""
    )
    print(
        f"\n{args.episodes} episodes of {args.env} ({what}; seeds {args.seed}–{args.seed + args.episodes - 1}), "
        f"{len(steps)} steps, median step (env and monitor) {1000 * statistics.median(steps):.1f} ms"
    )
    if ran:
        print("the script's episodes: " + ", ".join(ran))
    print((out / "rollouts.md").read_text())


def recorded_state_adapter() -> Any:
    """ManiSkill's observations named as the peer set's LeRobot dataset (`lerobot-recorded`) names what a robot
    records: the cameras as the `maniskill` adapter names them, `observation.state` in its meta/info.json's order
    (joint positions, the arm's joint velocities, the gripper's width, the hand's pose) and the action `action`."""
    from dataclasses import dataclass

    import numpy as np

    from robofailring.monitor.adapters import ManiSkillAdapter, Observed, as_vector, lookup

    @dataclass(frozen=True)
    class RecordedState(ManiSkillAdapter):
        name: str = "maniskill-recorded"
        action: str | None = "action"

        def observe(self, observation: Any, *, step: int) -> Observed:
            views = super().observe(observation, step=step).views
            qpos, qvel, hand = (
                as_vector(lookup(observation, key), f"step {step}: observation {key!r}")
                for key in ("agent/qpos", "agent/qvel", "extra/tcp_pose")
            )
            state = np.concatenate([qpos[:9], qvel[:7], qpos[7:9].sum(keepdims=True), hand[:7]])
            return Observed(views, {"observation.state": state})

    return RecordedState()


def run_script(
    monitored: Any,
    cut: Any,
    stepper_type: Any,
    faults: list[str],
    episode: int,
    env_id: str,
    steps: list[float],
) -> str:
    """One episode of peer_generate.py's motion-planned script through the monitor; returns what it injected."""
    from bench.peer_generate import AXES, SCRIPTS, Script

    fault = faults[episode % len(faults)]
    family = None if fault == "none" else fault
    turn = episode // len(faults)
    axis = AXES[turn % 3] if family in ("translation", "rotation") else ""
    sign = 1.0 if turn // 3 % 2 == 0 else -1.0
    timed = stepper_type(monitored)
    inner_step = timed.step

    def step(action: Any) -> Any:
        start = time.perf_counter()
        try:
            return inner_step(action)
        finally:
            steps.append(time.perf_counter() - start)

    timed.step = step
    script = Script(timed, family, axis, sign)
    try:
        SCRIPTS[env_id](script)
        script.hold()
        cut.cutting = True  # the script is done: its next step is the episode's last
        script.planner.close_gripper(t=1, gripper_state=script.planner.gripper_state)
    except EpisodeOver:
        pass
    return f"{fault}{'_' + axis if axis else ''}"


if __name__ == "__main__":
    main()
