"""Proactive stop in the simulator: the detector watches the robot live and stops it at the alarm.

    python examples/closed_loop_sim.py --task pick_cube --mode grasp --seed 11
    rerun recordings/closed_loop/pick_cube_grasp_seed11.rrd

A small dataset of the task is simulated once (cached), its failures become the memory (weight-free
`pixels` encoder), δ is calibrated on its successes unless --delta is given, then one new episode
runs twice: stopped at the first alarm, and left to run to its end. With the `pixels` encoder
S_t mostly reflects the scene layout, so for some seeds the alarm fires at frame 0.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rfr_viz import run_closed_loop
from robofailring import (
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
    parser.add_argument(
        "--target-fpr",
        type=float,
        default=None,
        help="α of the calibration (default: the smallest the successes allow)",
    )
    parser.add_argument("--episodes", type=int, default=4, help="memory episodes per failure family")
    parser.add_argument("--data", type=Path, default=default_cache_dir() / "closed-loop-data")
    parser.add_argument("--out", type=Path, default=Path("recordings/closed_loop"))
    parser.add_argument("--image-size", type=int, default=128, help="camera images, pixels a side")
    parser.add_argument("--frames", type=int, default=40, help="frames per episode")
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
    memory_dir = args.out / f"memory_{args.task}"
    # the paper's memory (no success runs): the closed loop stops at S_t ≥ δ
    memory, stats = build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=memory_dir,
            recipe=MemoryRecipe(encoder="pixels"),
            success_memory=False,
        )
    )
    print(f"memory: {len(memory)} entries from {stats.failures} failure episodes in {data}")
    if args.delta is None:
        successes = sum(not t.is_failure for t in load_dataset(data).trajectories())
        alpha = args.target_fpr or smallest_target_fpr(successes)  # split conformal needs n ≥ 1/α − 1
        calibration = calibrate(
            CalibrateConfig(
                data=DataSelection(data),
                memory=memory_dir,
                threshold_policy=ThresholdPolicy(target_fpr=alpha),
                split=None,
            )
        )
        print(
            f"calibrated δ = {calibration.delta:.4f} on {calibration.successes} successes (α = {alpha:.3f})"
        )
    detector = open_detector(memory_dir, delta=args.delta)  # δ: the one given, else the calibrated one

    result = run_closed_loop(
        memory=detector.memory,
        encoder=detector.encoder,
        task=args.task,
        mode=args.mode,
        seed=args.seed,
        delta=detector.delta,
        image_size=args.image_size,
        frames=args.frames,
        out=args.out / f"{args.task}_{args.mode}_seed{args.seed}.rrd",
    )
    if result.stop_frame is None:
        print(f"no alarm in {result.length} frames: the robot was never stopped")
    else:
        print(
            f"STOP at frame {result.stop_frame}/{result.length} (view {result.stop_view}, "
            f"T_s = {result.saving_ratio:.2f})"
        )
    watched = result.watched
    how = "stopped" if watched.stopped_early else "ran to its end"
    goal = "goal reached" if watched.outcome == "success" else "goal not reached"
    print(f"watched run:   {how} after {watched.frames} frames ({goal})")
    print(f"unstopped run: {result.unstopped.outcome} ({result.unstopped.label or 'goal reached'})")
    print(f"recording: {result.path}\n  rerun {result.path}")


if __name__ == "__main__":
    main()
