"""Probe (issue 31): a trained encoder trained on the hand camera's frames only (one per ID half), on the
peer set with every view fused by the max, with `per-view` fusion, and judged on the hand view alone.

Run: .venv/bin/python -m bench.experiments.probe_peer_hand_encoder
"""

from __future__ import annotations

import argparse
import time

from bench._timing import print_machine
from bench.bench_peer import PER_VIEW, evaluate_encoder, peer_set, print_targets
from bench.bench_quality import QualityRow, Variant, print_rows
from robofailring.data.selection import DataSelection
from robofailring.encoders.training import TrainEncoderConfig, train_encoder


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    print_machine()
    peer = peer_set(None, 2)
    cache = peer.root.parent
    specs = []
    for labels, name in (
        (peer.labels, "trained-encoder-hand"),
        (peer.swapped_labels, "trained-encoder-hand-swapped"),
    ):
        started = time.perf_counter()
        config = TrainEncoderConfig(
            data=DataSelection(peer.root, labels=labels, views="hand"), out=cache / name
        )
        trained = train_encoder(config, reuse=True)
        print(
            f"trained {trained} on the hand view of {labels.name}'s train half: {time.perf_counter() - started:.0f} s"
        )
        specs.append(f"trained:{trained}")
    variants = (
        Variant("hand-trained", {}),
        Variant("hand-trained-per-view", PER_VIEW.settings),
        Variant("hand-trained-hand-only", {"views": "hand"}),
    )
    rows = []
    for variant in variants:
        rows += evaluate_encoder(specs[0], specs[1], peer, alpha=0.05, out=cache / "runs", variant=variant)
    quality: list[QualityRow] = list(rows)
    print_rows(quality, 0.05)
    print_targets(rows)


if __name__ == "__main__":
    main()
