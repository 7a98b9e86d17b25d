"""The rollout monitor's cost (issue 52): the wrapper's step against the env's own and a bare `session.step`,
parity of its alarms with `detect` on the saved episodes, memory over 10,000 steps, a vector env of 4.

Run: .venv/bin/python -m bench.bench_monitor [--episodes 4] [--frames 40] [--long 10000]

The env is the embedded simulator (`SimEnv`, three cameras at --image-size, its scripted policy, faults
injected); the memory is built once from a small simulated set of the same task (pixels encoder, contrast rule
as calibrated by default; no embedding cache, so every step encodes its frames). 1. Overhead: the same seeded episodes run bare, then under `RolloutMonitor` saving
every episode; the session's own cost is `session.step` timed on the same frames. 2. Parity: `detect` on each
saved episode against the monitor's verdicts, frame for frame. 3. Memory: the process's resident memory over
--long steps of a cheap env replaying recorded frames under the monitor (frames written as they come).
4. A `SyncVectorEnv` of 4 `SimEnv`s under `VectorRolloutMonitor`. All printed side by side, one run.
"""

# ruff: noqa: E402  (the imports follow the thread settings, which must precede numpy)
from __future__ import annotations

import os

from bench._timing import print_machine

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse
import resource
import statistics
import tempfile
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np


def _rss_mib() -> float:
    """The process's resident memory now (MiB), from /proc."""
    with open("/proc/self/statm") as handle:
        pages = int(handle.read().split()[1])
    return pages * resource.getpagesize() / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--episodes", type=int, default=4, help="episodes of the overhead run (half grasp faults)"
    )
    parser.add_argument("--frames", type=int, default=40, help="frames per simulated episode")
    parser.add_argument("--image-size", type=int, default=128)
    parser.add_argument("--long", type=int, default=10_000, help="steps of the memory run")
    args = parser.parse_args()
    print_machine()

    import gymnasium as gym

    from robofailring import (
        SIM_ADAPTER,
        CachedEncoder,
        FailureDetector,
        FailureMemory,
        GenerateConfig,
        RolloutMonitor,
        SimEnv,
        VectorRolloutMonitor,
        generate_dataset,
        load_dataset,
        load_encoder,
        open_encoder,
    )

    work = Path(tempfile.mkdtemp(prefix="bench-monitor-"))
    config = GenerateConfig(
        out=work / "data",
        tasks=("pick_cube",),
        modes=("success", "grasp", "slip"),
        episodes=3,
        image_size=args.image_size,
        frames=args.frames,
        workers=2,
    )
    memory, _ = FailureMemory.build(
        load_dataset(generate_dataset(config)).trajectories(), open_encoder("pixels")
    )

    def fresh_detector() -> FailureDetector:
        """A detector with an encoder of its own and no cache (without one, an encoder keeps what it encoded
        in memory): every step encodes its frames, in the monitor and in the bare session alike."""
        return FailureDetector(memory, CachedEncoder(load_encoder("pixels"), enabled=False))

    detector = fresh_detector()
    modes = ("grasp", "success")

    def make_env() -> SimEnv:
        return SimEnv("pick_cube", modes=modes, image_size=args.image_size, frames=args.frames)

    # 1. the env alone, then under the monitor: the same seeded episodes
    bare_env, bare_steps = make_env(), []
    recorded: list[tuple[dict[str, Any], np.ndarray]] = []
    for episode in range(args.episodes):
        observation, _ = bare_env.reset(seed=episode, options={"mode": modes[episode % 2]})
        while True:
            action = observation["policy_action"]
            recorded.append((observation, action))
            start = time.perf_counter()
            observation, _, terminated, truncated, _ = bare_env.step(action)
            bare_steps.append(time.perf_counter() - start)
            if terminated or truncated:
                break

    class Timed(gym.Wrapper[dict[str, Any], np.ndarray, dict[str, Any], np.ndarray]):
        """The env's own step timed inside the monitor's step, so the monitor's own work is their difference."""

        def step(self, action: Any) -> Any:
            start = time.perf_counter()
            result = self.env.step(action)
            inner.append(time.perf_counter() - start)
            return result

    inner: list[float] = []
    monitored = RolloutMonitor(Timed(make_env()), detector, out=work / "rollouts", adapter=SIM_ADAPTER)
    wrapped_steps, verdicts = [], []
    for episode in range(args.episodes):
        observation, _ = monitored.reset(seed=episode, options={"mode": modes[episode % 2]})
        live = []
        while True:
            start = time.perf_counter()
            observation, _, terminated, truncated, info = monitored.step(observation["policy_action"])
            wrapped_steps.append(time.perf_counter() - start)
            live.append(info["robofailring"])
            if terminated or truncated:
                break
        verdicts.append(live)
    monitored.close()
    bare_detector = fresh_detector()
    session, session_steps = None, []
    for number, (observation, action) in enumerate(recorded):
        if number % args.frames == 0:
            session = bare_detector.session("pick_cube")
        observed = SIM_ADAPTER.observe(observation, step=number)
        signals = observed.signals | SIM_ADAPTER.action_signals(action, step=number)
        start = time.perf_counter()
        assert session is not None
        session.step(observed.views, signals=signals)
        session_steps.append(time.perf_counter() - start)
    env_ms, wrapped_ms, session_ms = (
        1000 * statistics.median(steps) for steps in (bare_steps, wrapped_steps, session_steps)
    )
    own_ms = 1000 * statistics.median(outer - env for outer, env in zip(wrapped_steps, inner, strict=True))

    # 2. parity: detect on each saved episode, frame for frame
    mismatched, frames, worst = 0, 0, 0.0
    for trajectory, live in zip(
        load_dataset(work / "rollouts" / "episodes").trajectories(), verdicts, strict=True
    ):
        trace = detector.run(trajectory)
        judged = trace.judged_scores_of(trace.rule)
        fused = np.nanmax(np.stack([judged[view] for view in trace.scored_views]), axis=0)
        for t, verdict in enumerate(live):
            frames += 1
            mismatched += bool(fused[t] >= trace.threshold) != verdict.alarm
            worst = max(worst, max(abs(float(judged[v][t]) - verdict.scores[v]) for v in trace.scored_views))
        mismatched += trace.t_det != live[-1].first_alarm

    # 3. memory over --long steps: a cheap env replaying the recorded frames
    class Replay(gym.Env[dict[str, Any], np.ndarray]):
        def __init__(self) -> None:
            self.t = 0

        def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
            self.t = 0
            return recorded[0][0], {"task": "pick_cube"}

        def step(self, action: Any) -> Any:
            self.t += 1
            return recorded[self.t % len(recorded)][0], 0.0, self.t >= args.long, False, {}

    rss = {}
    long_run = RolloutMonitor(Replay(), fresh_detector(), out=work / "long", adapter=SIM_ADAPTER)
    long_run.reset()
    start = time.perf_counter()
    for step in range(args.long):
        long_run.step(recorded[step % len(recorded)][1])
        if step + 1 in (1_000, args.long // 2, args.long):
            rss[step + 1] = _rss_mib()
    long_seconds = time.perf_counter() - start
    long_run.close()

    # 4. a vector env of 4 simulators
    envs = gym.vector.SyncVectorEnv([partial(make_env) for _ in range(4)])
    vector = VectorRolloutMonitor(envs, fresh_detector(), out=work / "vector", adapter=SIM_ADAPTER)
    observations, _ = vector.reset(seed=0)
    vector_steps = []
    for _ in range(2 * args.frames + 2):
        start = time.perf_counter()
        observations, *_ = vector.step(observations["policy_action"])
        vector_steps.append(time.perf_counter() - start)
    vector.close()
    kept = load_dataset(work / "vector" / "episodes").trajectories()
    vector_episodes = [t for t in kept if t.outcome is not None]

    print(
        f"\n{args.episodes} episodes × {args.frames} frames, 3 views at {args.image_size} px, pixels encoder"
    )
    print("| measure | value |")
    print("|---|---|")
    print(f"| env step alone (median) | {env_ms:.2f} ms |")
    print(f"| bare session.step (median) | {session_ms:.2f} ms |")
    print(f"| wrapped step (median; env + session + episode writing) | {wrapped_ms:.2f} ms |")
    print(f"| the monitor's own work per step (median of wrapped − its env step) | {own_ms:.2f} ms |")
    print(f"| wrapped / env step alone | {wrapped_ms / env_ms:.2f}× |")
    print(f"| monitor's own work / env step alone | {own_ms / env_ms:.2f}× |")
    print(f"| monitor's own work / bare session.step | {own_ms / session_ms:.2f}× |")
    print(f"| parity: frames whose alarm differs from detect (+ t_det) | {mismatched} of {frames} |")
    print(f"| parity: largest score difference | {worst:.2e} |")
    print(f"| memory run: {args.long} steps | {long_seconds:.0f} s |")
    print(
        "| resident memory at steps "
        + ", ".join(map(str, rss))
        + " | "
        + ", ".join(f"{value:.0f}" for value in rss.values())
        + " MiB |"
    )
    print(
        f"| vector env of 4: step (median) | {1000 * statistics.median(vector_steps):.1f} ms, "
        f"{len(vector_episodes)} finished episodes kept |"
    )


if __name__ == "__main__":
    main()
