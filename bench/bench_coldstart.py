"""From zero failures to a full memory: recall, FPR, T_s and AUC at one α as labelled failures are added.

Run: .venv/bin/python -m bench.bench_coldstart [--encoder SPEC]... [--train-encoder] [--alpha 0.05]
     [--growth 0,1,2,4] [--id-episodes N --id-successes N --ood-episodes N --ood-successes N]

On the embedded benchmark (`bench/bench_quality.py`'s simulated ID and OOD sets, cached), the memory
is built from every training success run and 0, 1, 2, 4, … training failures per task
(`EvaluateConfig.failures_per_task`, a fixed pseudo-random choice), then all of them. Each level is
judged by its tasks' default rule: `novelty` with no failure (N_t = 1 − S⁺_t ≥ η), `contrast` from
the first labelled failure on; every threshold is split-conformal at α on the ID training successes.
The other rules' rows are printed beside it. `--train-encoder` trains an encoder on the ID
training split (cached beside the sets, as bench_quality's) and adds its rows.

Two recalls per row: at the calibrated threshold (its FPR is the test set's own, which may exceed
α), and at the best threshold whose FPR on the test set itself is ≤ α (ROC, an oracle: how far the
rule separates failures from successes at that FPR, whatever the calibration). The targets of
issue 22 are printed from both. Smaller sets than bench_quality's (a loaded machine) are chosen
with the size options and cached under their own folder.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bench._timing import print_machine
from bench.bench_quality import ID_EPISODES, ID_SUCCESSES, OOD_EPISODES, OOD_SUCCESSES, _pct, datasets
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.rules import default_rule
from robofailring.encoders import default_cache_dir, encoder_slug, load_encoder
from robofailring.encoders.training import TrainEncoderConfig, train_encoder
from robofailring.evaluation.job import EvaluateConfig, run_evaluation
from robofailring.evaluation.per_rule import RuleResult, scored_by_rule
from robofailring.evaluation.result import EvaluationResult
from robofailring.memory.recipe import MemoryRecipe


@dataclass(frozen=True)
class GrowthRow:
    encoder: str
    test_set: str
    failures_per_task: int | None  # None: all training failures
    rule: RuleResult
    default: bool  # the rule the level is judged by (its tasks' default)
    failures: int
    successes: int
    oracle_recall: float  # recall at the best threshold whose FPR on this test set is ≤ α


def oracle_recall(result: EvaluationResult, rule: RuleResult, alpha: float) -> float:
    """Recall at the lowest threshold that fires on at most ⌊α·n⌋ of the n test successes (peak scores)."""
    labels = {trajectory.key: trajectory for trajectory in result.scored}
    scored = scored_by_rule(result.traces, labels, rule.rule)
    peaks = {
        kind: np.nan_to_num(
            np.asarray([float(t.scores().max()) for t in scored if t.is_failure is kind]), nan=-np.inf
        )
        for kind in (True, False)
    }
    successes = np.sort(peaks[False])[::-1]
    allowed = math.floor(alpha * successes.size + 1e-9)  # false alarms α allows on this test set
    if not peaks[True].size:
        return float("nan")
    if allowed >= successes.size:
        return 1.0
    threshold = np.nextafter(successes[allowed], np.inf)  # just above the first success it must not fire on
    return float(np.count_nonzero(peaks[True] >= threshold)) / peaks[True].size


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
            data=DataSelection(in_dist),
            recipe=MemoryRecipe(encoder=encoder),
            out=out / slug / f"failures-{name}",
            threshold_policy=ThresholdPolicy(alpha),
            memory_out=out / slug / f"failures-{name}" / "memory",
            name="in-distribution",
            failures_per_task=level,
        )
        ood = replace(
            base,
            memory=base.memory_out,
            test_data=base.data.other(out_dist),
            test_split="ood",
            name="ood",
        )
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
                        oracle_recall(result, rule, alpha),
                    )
                )
    return rows


def print_rows(rows: list[GrowthRow], alpha: float) -> None:
    print(
        f"\n| encoder | test set | labelled failures / task | rule | threshold | Recall (%) | FPR (%) | "
        f"Recall at test FPR ≤ α (%) | T_s mean (%) | AUC | failures / successes tested |  "
        f"(α = {alpha:g}; * = the level's default rule)"
    )
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        level = "all" if row.failures_per_task is None else str(row.failures_per_task)
        rule = row.rule
        print(
            f"| {row.encoder} | {row.test_set} | {level} | {rule.rule.name}{' *' if row.default else ''} | "
            f"{rule.rule.symbol} = {rule.threshold:.4f} | {_pct(rule.recall)} | {_pct(rule.fpr)} | "
            f"{_pct(row.oracle_recall)} | {_pct(rule.ts_mean)} | {rule.auc:.3f} | {row.failures} / {row.successes} |"
        )


def print_curve(rows: list[GrowthRow]) -> None:
    """The learning curve: the default rule's recall and FPR per level (and its recall at test FPR ≤ α),
    ID and OOD side by side."""
    print(
        "\nlearning curve (default rule per level): recall % / FPR % at the calibrated threshold "
        "[recall % at test FPR ≤ α]"
    )
    for encoder in dict.fromkeys(row.encoder for row in rows):
        for test_set in ("ID", "OOD"):
            cells = [
                f"{'all' if r.failures_per_task is None else r.failures_per_task}: {r.rule.rule.name} "
                f"{_pct(r.rule.recall).strip()} / {_pct(r.rule.fpr).strip()} [{_pct(r.oracle_recall).strip()}]"
                for r in rows
                if r.default and r.encoder == encoder and r.test_set == test_set
            ]
            print(f"  {encoder} {test_set}: " + " → ".join(cells))


def print_targets(rows: list[GrowthRow], alpha: float) -> None:
    """Issue 22's targets: novelty alone ≥ 60 % recall at ≤ α FPR in distribution; 2 labelled failures per
    task close at least half of the recall gap between novelty (0) and the full memory (all)."""
    print(f"\ntargets (α = {alpha:g}): calibrated = at the conformal threshold; oracle = at test FPR ≤ α")
    for encoder in dict.fromkeys(row.encoder for row in rows):
        for test_set in ("ID", "OOD"):
            level = {
                r.failures_per_task: r
                for r in rows
                if r.default and r.encoder == encoder and r.test_set == test_set
            }
            if 0 not in level:
                continue
            novelty = level[0]
            met = novelty.rule.recall >= 0.6 and novelty.rule.fpr <= alpha + 1e-9
            print(
                f"  {encoder} {test_set} novelty ≥ 60 % recall at ≤ {100 * alpha:g} % FPR: calibrated "
                f"{_pct(novelty.rule.recall).strip()} % at {_pct(novelty.rule.fpr).strip()} % FPR "
                f"({'met' if met else 'not met'}); oracle {_pct(novelty.oracle_recall).strip()} % "
                f"({'met' if novelty.oracle_recall >= 0.6 else 'not met'})"
            )
            if 2 not in level or None not in level:
                continue
            for name, recall in (
                ("calibrated", lambda r: r.rule.recall),
                ("oracle", lambda r: r.oracle_recall),
            ):
                zero, two, full = recall(level[0]), recall(level[2]), recall(level[None])
                if full <= zero:
                    verdict = f"no gap to close (all {_pct(full).strip()} % ≤ novelty {_pct(zero).strip()} %)"
                else:
                    closed = (two - zero) / (full - zero)
                    verdict = (
                        f"0 → 2 → all: {_pct(zero).strip()} → {_pct(two).strip()} → {_pct(full).strip()} %, "
                        f"{100 * closed:.0f} % of the gap closed ({'met' if closed >= 0.5 else 'not met'})"
                    )
                print(
                    f"  {encoder} {test_set} 2 labelled failures / task close ≥ half the gap, {name}: {verdict}"
                )


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
    parser.add_argument("--train-encoder", action="store_true", help="add a trained encoder's rows")
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
    print_machine()
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
    out = default_cache_dir() / "bench-coldstart" / "runs" / in_dist.name  # one folder per set size
    encoders = list(args.encoder or ["pixels"])
    if args.train_encoder:
        started = time.perf_counter()
        trained = train_encoder(
            TrainEncoderConfig(
                data=in_dist,
                out=in_dist.parent / f"trained-encoder{in_dist.name.removeprefix('sim-id')}",
            ),
            reuse=True,
        )  # at bench_quality's size, the one bench_quality trains
        print(
            f"trained encoder {trained}: {time.perf_counter() - started:.0f} s (0 when reused from the cache)"
        )
        encoders.append(f"trained:{trained}")
    rows: list[GrowthRow] = []
    for encoder in encoders:
        started = time.perf_counter()
        rows += growth_rows(
            encoder, in_dist, out_dist, levels=parse_levels(args.growth), alpha=args.alpha, out=out
        )
        print(f"{encoder}: {time.perf_counter() - started:.0f} s")
    print_rows(rows, args.alpha)
    print_curve(rows)
    print_targets(rows, args.alpha)


if __name__ == "__main__":
    main()
