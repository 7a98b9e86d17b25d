"""Probe (issue 31): the `pixels` encoder with a larger thumbnail on the peer set, max and per-view fusion.

Run: .venv/bin/python -m bench.experiments.probe_peer_thumbnail [SIZE]   (default 48; the encoder's own is 24)

The thumbnail side is the module constant `robofailring.encoders.pixels.THUMBNAIL`; this probe sets it
(and the identity, so no cached embedding of the 24 px encoder is reused) before the encoder is made.
"""

from __future__ import annotations

import argparse

import robofailring.encoders.pixels as pixels
from bench._timing import print_machine


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "size", type=int, nargs="?", default=48, help="thumbnail side in pixels (the encoder's own: 24)"
    )
    size = parser.parse_args().size
    print_machine()
    pixels.THUMBNAIL = size  # type: ignore[misc]
    pixels.IDENTITY = f"pixels-v2-{size}px-{pixels.DIM}d"  # type: ignore[misc]
    from bench.bench_peer import PER_VIEW, evaluate_encoder, peer_set, print_targets
    from bench.bench_quality import Variant, print_rows

    peer = peer_set(None, 2)
    rows = []
    for label, variant in ((f"thumb{size}", Variant("default", {})), (f"thumb{size}-per-view", PER_VIEW)):
        rows += evaluate_encoder(
            "pixels",
            "pixels",
            peer,
            alpha=0.05,
            out=peer.root.parent / "runs",
            variant=Variant(label, variant.settings),
        )
    print_rows(list(rows), 0.05)
    print_targets(rows)


if __name__ == "__main__":
    main()
