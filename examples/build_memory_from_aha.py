"""Build a failure memory from an AHA FailGen (RLBench) folder with real CLIP weights, then detect.

    python examples/build_memory_from_aha.py /data/aha_failgen /data/new_episode \\
        --encoder open_clip:ViT-B-32:/models/vit-b-32-openai.pt --task put_block_in_bin

The encoder spec takes an open_clip pretrained tag (`open_clip:ViT-B-32:openai`, needs the weights in
the local Hugging Face cache or network access) or a local checkpoint file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from robofailring import (
    BuildMemoryConfig,
    DataSelection,
    MemoryRecipe,
    build_memory,
    load_trajectory,
    open_detector,
)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "dataset", type=Path, help="AHA FailGen root: <task>_<failure>_wp<k>_episode<e>/ folders"
    )
    parser.add_argument("episode", type=Path, help="an episode folder to run the detector on")
    parser.add_argument("--encoder", default="open_clip:ViT-B-32:openai")
    parser.add_argument("--task", default=None, help="task of the episode, if its folder name does not say")
    parser.add_argument("--memory", type=Path, default=Path("memories/aha-vit-b-32"))
    parser.add_argument(
        "--delta", type=float, default=None, help="default: calibrated δ, else the paper's 0.92"
    )
    args = parser.parse_args()

    # embeddings are cached: a rerun encodes nothing; the manifest records the encoder spec for `detect`
    memory, stats = build_memory(
        BuildMemoryConfig(
            data=DataSelection(args.dataset), out=args.memory, recipe=MemoryRecipe(encoder=args.encoder)
        )
    )
    print(f"{args.dataset}: {memory.manifest.layout} layout")
    print(
        f"memory: {len(memory)} entries over {len(memory.tasks)} tasks; {len(stats.skipped_views)} views skipped"
    )

    detector = open_detector(args.memory, delta=args.delta)
    trace = detector.run(load_trajectory(args.episode, task=args.task))
    if trace.t_det is None or trace.detected_view is None:
        print(f"no failure detected in {trace.length} frames (δ = {trace.delta:.3f})")
        return
    top = trace.neighbors(trace.detected_view, trace.t_det)[0]
    print(
        f"failure at frame {trace.t_det}/{trace.length} in {trace.detected_view}: S_t = {top.similarity:.3f}"
    )
    print(f"nearest memory entry: {top.entry.task} {top.entry.symbol} -> {top.entry.description}")


if __name__ == "__main__":
    main()
