"""Compare two encoders on the same split (paper Table 3): each memory calibrated, one table.

    python examples/compare_encoders.py DATA --encoder open_clip:ViT-B-32:openai \\
        --encoder open_clip:ViT-L-14:/models/vit-l-14.pt --out comparisons/
"""

from __future__ import annotations

import argparse
from pathlib import Path

from robofailring import (
    CompareEncodersConfig,
    DataSelection,
    ThresholdPolicy,
    compare_encoders,
    comparison_table,
)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("data", type=Path, help="dataset with train/test splits (any supported layout)")
    parser.add_argument(
        "--encoder", action="append", default=[], help="repeat for each encoder (two or more)"
    )
    parser.add_argument("--out", type=Path, default=Path("comparisons"))
    parser.add_argument("--target-fpr", type=float, default=0.05)
    args = parser.parse_args()
    encoders = tuple(args.encoder) or ("pixels", "open_clip:ViT-B-32:openai")
    results = compare_encoders(
        CompareEncodersConfig(
            data=DataSelection(args.data),
            threshold_policy=ThresholdPolicy(target_fpr=args.target_fpr),
            out=args.out,
            encoders=encoders,
        )
    )
    print(comparison_table(results))


if __name__ == "__main__":
    main()
