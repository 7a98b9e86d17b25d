"""Your own robot loop, watched live in Rerun: the step API with the Rerun sink, on the simulated robot.

    rerun &                                              # a viewer on the default port
    python examples/live_robot_sim.py --task pick_cube --mode grasp --seed 11
    python examples/live_robot_sim.py --spawn            # or start one
    python examples/live_robot_sim.py --save recordings/live/pick_cube.rrd   # or only record it

A small dataset of the task is simulated once (cached) and its failures become the memory
(weight-free `pixels` encoder; δ calibrated on its successes unless --delta is given). Then one new
episode runs; each control step's three camera images go to `session.step(...)`, whose sink streams
them, S_t, δ, State_t, the neighbours and the alarm to the viewer with the entity paths of a replay.
The robot is stopped at the first alarm. The loop itself is the few lines under "the robot loop".
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rfr_viz import LiveRecording, LiveTarget
from robofailring import (
    SIM_VIEWS,
    BuildMemoryConfig,
    CalibrateConfig,
    DataSelection,
    GenerateConfig,
    MemoryRecipe,
    ThresholdPolicy,
    build_memory,
    calibrate,
    default_cache_dir,
    generate_dataset,
    load_dataset,
    open_detector,
    run_episode,
    smallest_target_fpr,
)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--task", default="pick_cube")
    parser.add_argument("--mode", default="grasp", help="failure family, concrete mode or 'success'")
    parser.add_argument("--seed", type=int, default=11, help="the new episode (not one of the memory's)")
    parser.add_argument("--delta", type=float, default=None, help="default: calibrated on the successes")
    parser.add_argument("--episodes", type=int, default=4, help="memory episodes per failure family")
    parser.add_argument("--data", type=Path, default=default_cache_dir() / "closed-loop-data")
    parser.add_argument("--image-size", type=int, default=128, help="camera images, pixels a side")
    parser.add_argument("--frames", type=int, default=40, help="frames per episode")
    parser.add_argument(
        "--connect", default=None, help="viewer URL (default rerun+http://127.0.0.1:9876/proxy)"
    )
    parser.add_argument("--spawn", action="store_true", help="start a viewer")
    parser.add_argument("--save", type=Path, default=None, help="also record the stream to this .rrd")
    args = parser.parse_args()

    data = generate_dataset(
        GenerateConfig(
            out=args.data / f"{args.task}_{args.image_size}px_{args.frames}f",
            tasks=(args.task,),
            episodes=args.episodes,
            image_size=args.image_size,
            frames=args.frames,
        )
    )
    trajectories = list(load_dataset(data))
    memory_dir = Path(args.data) / f"memory_{args.task}_{args.image_size}px_{args.frames}f"
    # the paper's memory (no success runs): the robot is stopped at S_t ≥ δ
    memory, stats = build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=memory_dir,
            recipe=MemoryRecipe(encoder="pixels"),
            success_memory=False,
        )
    )
    if args.delta is None:  # split conformal at the smallest α its successes allow (n ≥ 1/α − 1)
        alpha = smallest_target_fpr(sum(not t.is_failure for t in trajectories))
        calibrate(
            CalibrateConfig(
                data=DataSelection(data),
                memory=memory_dir,
                threshold_policy=ThresholdPolicy(target_fpr=alpha),
                split=None,
            )
        )
    detector = open_detector(memory_dir, delta=args.delta)  # δ: the one given, else the calibrated one
    print(f"memory: {len(memory)} entries from {stats.failures} failure episodes; δ = {detector.delta:.4f}")

    connect = args.connect or (None if args.spawn or args.save else "rerun+http://127.0.0.1:9876/proxy")
    target = LiveTarget(connect=connect, spawn=args.spawn, save=args.save)
    fps = trajectories[0].fps  # the simulated episodes' frame rate: their dataset records it
    # the robot loop: one session per episode, one step per control tick, stop at the alarm
    with LiveRecording.open(detector, args.task, views=SIM_VIEWS, target=target, fps=fps) as live:
        session = detector.session(args.task, sink=live)
        with run_episode(
            args.task, args.mode, args.seed, image_size=args.image_size, frames=args.frames
        ) as run:
            for images in run:  # {"front": rgb, "overhead": rgb, "wrist": rgb}
                if session.step(images).alarm:
                    run.stop()
            result = run.run_to_end()

    if live.fired_at is None:
        print(f"no alarm in {live.steps} steps; goal check: {result.outcome}")
    else:
        print(
            f"STOP at step {live.fired_at} (view {live.report.view if live.report else '?'}); goal check: {result.outcome}"
        )
    if args.save:
        print(f"recording: {args.save}\n  rerun {args.save}")


if __name__ == "__main__":
    main()
