"""bench_peer's cells (pixels, α = 0.05) for named settings of the robot's signals and their calibration (issue 41),
where `bench_peer.py --variant` cannot say them (the chosen dimensions hold commas).

Run: .venv/bin/python -m bench.experiments.peer_variants [LABEL]...

Each LABEL is one block of bench_peer's four cells, its rows and the targets printed as bench_peer prints them;
its settings are in VARIANTS (CHOSEN: bench_peer's chosen dimensions). Without labels: every variant.
"""

from __future__ import annotations

import argparse
from typing import Any

from bench._timing import print_machine
from bench.bench_peer import CHOSEN as CHOSEN_BY_STATE
from bench.bench_peer import PeerRow, Variant, evaluate_encoder, peer_set, print_targets
from bench.bench_quality import QualityRow, print_rows

CHOSEN = CHOSEN_BY_STATE["privileged"]  # the dimensions these variants were measured with
VARIANTS: dict[str, dict[str, Any]] = {
    "both": {},  # the defaults, every dimension
    "signals": {"modality": "signals"},
    "vision": {"signals": "none"},
    "chosen-both": {"signals": CHOSEN},  # the defaults, the chosen dimensions
    "chosen-sig": {"signals": CHOSEN, "modality": "signals"},
    "chosen-both-max": {
        "signals": CHOSEN,
        "fusion": "max",
        "signal_start_weight": 0.5,
    },  # the defaults before
    "chosen-sw0": {"signals": CHOSEN, "fusion": "max", "signal_start_weight": 0.0},
    "chosen-pmt": {"signals": CHOSEN, "band_scope": "task", "signal_start_weight": 0.5},
    "chosen-pmt0": {"signals": CHOSEN, "band_scope": "task", "signal_start_weight": 0.0},
    "chosen-t0": {"signals": CHOSEN, "fusion": "max", "band_scope": "task", "signal_start_weight": 0.0},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("labels", nargs="*", help=f"variants, of {', '.join(VARIANTS)} (default: all)")
    args = parser.parse_args()
    unknown = [label for label in args.labels if label not in VARIANTS]
    if unknown:
        parser.error(f"unknown variant {unknown[0]!r}; choose from {', '.join(VARIANTS)}")
    print_machine()
    peer = peer_set(None, 2, "privileged")
    rows: list[PeerRow] = []
    for label in args.labels or VARIANTS:
        variant = Variant(label, VARIANTS[label])
        rows += evaluate_encoder(
            "pixels", "pixels", peer, alpha=0.05, out=peer.root.parent / "runs", variant=variant
        )
    for row in rows:
        print(f"{row.encoder} {row.protocol}: evaluated in {row.seconds:.0f} s")
    print_targets(rows)
    quality: list[QualityRow] = list(rows)
    print_rows(quality, 0.05)


if __name__ == "__main__":
    main()
