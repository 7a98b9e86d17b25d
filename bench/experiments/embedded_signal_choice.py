"""bench_quality's four cells (pixels, α = 0.05) with the defaults (`--signals auto`: each task's dimensions chosen
from its training runs, issue 51) beside every signal's dimensions kept (the defaults before), each cell per
modality with recall per failure family: the embedded benchmark must not drop.

Run: .venv/bin/python -m bench.experiments.embedded_signal_choice
"""

from __future__ import annotations

import argparse

from bench._timing import print_machine
from bench.bench_quality import (
    QualityRow,
    Variant,
    bench_sets,
    evaluate_encoder,
    print_modalities,
    print_rows,
)
from robofailring.encoders import default_cache_dir

# every state and action signal the embedded set records, named: no choice made (the defaults before issue 51)
EVERY_DIMENSION = "joint_positions,gripper_width,ee_pose,action"


def main() -> None:
    argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    ).parse_args()
    print_machine()
    in_dist, out_dist, swapped = bench_sets(2)
    out = default_cache_dir() / "bench-quality" / "runs"
    rows: list[QualityRow] = []
    for variant in (Variant("defaults", {}), Variant("every-dimension", {"signals": EVERY_DIMENSION})):
        rows += evaluate_encoder(
            "pixels", in_dist, out_dist, alpha=0.05, out=out, swapped=(swapped, "pixels"), variant=variant
        )
    for row in rows:
        print(f"{row.encoder} {row.protocol}: evaluated in {row.seconds:.0f} s")
    print_rows(rows, 0.05)
    print_modalities(rows)


if __name__ == "__main__":
    main()
