"""A real third-party env under the rollout monitor (issue 52, item 5): ManiSkill3's PickCube-v1 in the bench venv
that `bench/setup_peer.sh` makes, judged by a memory of ManiSkill3 runs, its rollout summary printed.

Run (in the bench venv; the project's core dependencies beside it in a folder of their own, so the peer venv
is left as setup_peer.sh made it):

    ~/.cache/robofailring/peer-env/venv/bin/python -m pip install --target ~/.cache/robofailring/monitor-deps \\
        faiss-cpu opencv-python-headless pyyaml typer tqdm
    source ~/.cache/robofailring/peer-env/env.sh
    PYTHONPATH=src:.:bench:$HOME/.cache/robofailring/monitor-deps ~/.cache/robofailring/peer-env/venv/bin/python \\
        bench/bench_monitor_maniskill.py --memory MEMORY [--episodes 20] [--policy random]

MEMORY is a memory built (in the project's venv, `robofailring build-memory`) from ManiSkill3 PickCube-v1
runs with the same cameras, e.g. bench_peer.py's set (docs/bench_peer.md). The policy is ManiSkill's own
random action sampler unless --policy zero; the episode's outcome is ManiSkill's `success`.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from bench._timing import print_machine


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--memory", type=Path, required=True, help="a memory of ManiSkill3 PickCube-v1 runs")
    parser.add_argument("--env", default="PickCube-v1")
    parser.add_argument("--task", default=None, help="the memory's task (default: the env id)")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--max-steps", type=int, default=50)
    parser.add_argument("--image-size", type=int, default=128)
    parser.add_argument("--policy", choices=("random", "zero"), default="random")
    parser.add_argument(
        "--out", type=Path, default=None, help="where the rollouts go (default: a temporary folder)"
    )
    args = parser.parse_args()
    print_machine(libraries=("mani_skill", "gymnasium"))

    import gymnasium as gym
    import mani_skill.envs  # noqa: F401  (registers the envs)
    import numpy as np

    from robofailring import RolloutMonitor, open_detector

    env = gym.make(
        args.env,
        obs_mode="rgb",
        num_envs=1,
        max_episode_steps=args.max_steps,
        sensor_configs={"width": args.image_size, "height": args.image_size},
    )
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-monitor-maniskill-"))
    monitored = RolloutMonitor(
        env, open_detector(args.memory), out=out, adapter="maniskill", task=args.task or args.env
    )
    steps: list[float] = []
    with monitored:
        for episode in range(args.episodes):
            monitored.reset(seed=episode)
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
    print(
        f"\n{args.episodes} episodes of {args.env} ({args.policy} policy), median step {1000 * statistics.median(steps):.1f} ms"
    )
    print((out / "rollouts.md").read_text())


if __name__ == "__main__":
    main()
