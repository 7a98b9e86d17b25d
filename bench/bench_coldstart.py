"""From zero failures to a full memory: recall, FPR, T_s and AUC at one α as labelled failures are added.

Run: .venv/bin/python bench/bench_coldstart.py [--encoder SPEC]... [--alpha 0.05] [--growth 0,1,2,4]
     [--id-episodes N --id-successes N --ood-episodes N --ood-successes N]

On the embedded benchmark (`bench/bench_quality.py`'s simulated ID and OOD sets, cached), the memory
is built from every training success run and 0, 1, 2, 4, … training failures per task
(`EvaluateConfig.failures_per_task`, a fixed pseudo-random choice), then all of them. Each level is
judged by its tasks' default rule: `novelty` with no failure (N_t = 1 − S⁺_t ≥ η), `contrast` from
the first labelled failure on; every threshold is split-conformal at α on the ID training successes.
The other rules' rows are printed beside it. Smaller sets than bench_quality's (a loaded machine)
are chosen with the size options and cached under their own folder.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, replace
from pathlib import Path

from bench_quality import ID_EPISODES, ID_SUCCESSES, OOD_EPISODES, OOD_SUCCESSES, _pct, datasets

from robofailring.detection.rules import default_rule
from robofailring.encoders import default_cache_dir, encoder_slug, load_encoder
from robofailring.evaluation.per_rule import RuleResult
from robofailring.evaluation.run import EvaluateConfig, run_evaluation


@dataclass(frozen=True)
class GrowthRow:
    encoder: str
    test_set: str
    failures_per_task: int | None  # None: all training failures
    rule: RuleResult
    default: bool  # the rule the level is judged by (its tasks' default)
    failures: int
    successes: int


def growth_rows(
    encoder: str,
    in_dist: Path,
    out_dist: Path,
    *,
    levels: list[int | None],
    alpha: float,
    out: Path,
) -> list[GrowthRow]:
    """Per level of labelled failures per task: the ID and OOD evaluations of one memory, every rule at α."""
    slug = encoder_slug(load_encoder(encoder).identity)
    rows = []
    for level in levels:
        name = "all" if level is None else str(level)
        base = EvaluateConfig(
            data=in_dist,
            out=out / slug / f"failures-{name}",
            encoder=encoder,
            target_fpr=alpha,
            memory_out=out / slug / f"failures-{name}" / "memory",
            name="in-distribution",
            failures_per_task=level,
        )
        ood = replace(base, memory=base.memory_out, test_data=out_dist, test_split="ood", name="ood")
        judged_by = default_rule(successes=True, failures=level != 0)
        for label, config in (("ID", base), ("OOD", ood)):
            result = run_evaluation(config)
            for rule in result.rules.values():
                rows.append(
                    GrowthRow(
                        encoder,
                        label,
                        level,
                        rule,
                        rule.rule is judged_by,
                        result.failures,
                        result.successes,
                    )
                )
    return rows


def print_rows(rows: list[GrowthRow], alpha: float) -> None:
    print(
        f"\n| encoder | test set | labelled failures / task | rule | threshold | Recall (%) | FPR (%) | "
        f"T_s mean (%) | AUC | failures / successes tested |  (α = {alpha:g}; * = the level's default rule)"
    )
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        level = "all" if row.failures_per_task is None else str(row.failures_per_task)
        rule = row.rule
        print(
            f"| {row.encoder} | {row.test_set} | {level} | {rule.rule.name}{' *' if row.default else ''} | "
            f"{rule.rule.symbol} = {rule.threshold:.4f} | {_pct(rule.recall)} | {_pct(rule.fpr)} | "
            f"{_pct(rule.ts_mean)} | {rule.auc:.3f} | {row.failures} / {row.successes} |"
        )


def print_curve(rows: list[GrowthRow]) -> None:
    """The learning curve: the default rule's recall and FPR per level, ID and OOD side by side."""
    print("\nlearning curve (default rule per level): recall % / FPR %")
    for encoder in dict.fromkeys(row.encoder for row in rows):
        for test_set in ("ID", "OOD"):
            cells = [
                f"{'all' if r.failures_per_task is None else r.failures_per_task}: {r.rule.rule.name} "
                f"{_pct(r.rule.recall).strip()} / {_pct(r.rule.fpr).strip()}"
                for r in rows
                if r.default and r.encoder == encoder and r.test_set == test_set
            ]
            print(f"  {encoder} {test_set}: " + " → ".join(cells))


def parse_levels(text: str) -> list[int | None]:
    """`0,1,2,4` → [0, 1, 2, 4, None]: the levels, then the full memory."""
    levels: list[int | None] = [int(part) for part in text.split(",") if part.strip()]
    return [*levels, None]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--encoder", action="append", help="encoder spec (repeatable; default: pixels)")
    parser.add_argument("--alpha", type=float, default=0.05, help="target FPR α of every rule")
    parser.add_argument("--growth", default="0,1,2,4", help="labelled failures per task, then all")
    parser.add_argument("--workers", type=int, default=2, help="simulation processes")
    parser.add_argument(
        "--id-episodes", type=int, default=ID_EPISODES, help="ID episodes per task and family"
    )
    parser.add_argument("--id-successes", type=int, default=ID_SUCCESSES, help="ID successes per task")
    parser.add_argument(
        "--ood-episodes", type=int, default=OOD_EPISODES, help="OOD episodes per task and family"
    )
    parser.add_argument("--ood-successes", type=int, default=OOD_SUCCESSES, help="OOD successes per task")
    args = parser.parse_args()
    start = time.perf_counter()
    in_dist, out_dist = datasets(
        args.workers,
        id_episodes=args.id_episodes,
        id_successes=args.id_successes,
        ood_episodes=args.ood_episodes,
        ood_successes=args.ood_successes,
    )
    print(
        f"datasets (cached): {in_dist}, {out_dist} ({time.perf_counter() - start:.0f} s to simulate or find); "
        f"ID {args.id_episodes} episodes per task and failure family, {args.id_successes} successes per task "
        f"(even episodes train, odd test); OOD {args.ood_episodes} per family, {args.ood_successes} successes per task"
    )
    out = default_cache_dir() / "bench-coldstart" / "runs"
    rows: list[GrowthRow] = []
    for encoder in args.encoder or ["pixels"]:
        started = time.perf_counter()
        rows += growth_rows(
            encoder, in_dist, out_dist, levels=parse_levels(args.growth), alpha=args.alpha, out=out
        )
        print(f"{encoder}: {time.perf_counter() - started:.0f} s")
    print_rows(rows, args.alpha)
    print_curve(rows)


if __name__ == "__main__":
    main()
