"""Detection quality: both scoring rules at one α, in distribution, out of distribution, and OOD with
deployment successes, on simulated sets (cached under the robofailring cache dir).

Run: .venv/bin/python bench/bench_quality.py [--encoder SPEC]... [--alpha 0.05] [--success-step S]...
     [--train-encoder]

Each encoder spec is one more block of rows (e.g. `--encoder pixels --encoder trained:DIR`);
`--train-encoder` trains one on the ID training split (cached) and adds its rows, with the training
time; each `--success-step` (success-frame thinning, 0 = every frame) is one more block per encoder.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

from robofailring.encoders import default_cache_dir, encoder_slug, load_encoder
from robofailring.encoders.training import TrainEncoderConfig, train_encoder
from robofailring.evaluation.run import EvaluateConfig, EvaluationResult, run_evaluation, write_evaluation
from robofailring.memory.failure import FailureMemory
from robofailring.memory.thinning import DEFAULT_STEP
from robofailring.progress import progress_bar
from robofailring.sim import TASKS, GenerateConfig, generate_dataset

IMAGE_SIZE = 64
FRAMES = 28
ID_EPISODES = 8  # per task and failure family: 4 tasks x 7 families x 8 = 224 failures, half tested
ID_SUCCESSES = 26  # per task: 104 successes, 52 train (calibration) and 52 test
OOD_EPISODES = 2  # per task and failure family, all tested
OOD_SUCCESSES = 8  # per task: 2 join the success memory under the deployment protocol, 6 tested


def datasets(
    workers: int = 2,
    *,
    id_episodes: int = ID_EPISODES,
    id_successes: int = ID_SUCCESSES,
    ood_episodes: int = OOD_EPISODES,
    ood_successes: int = OOD_SUCCESSES,
) -> tuple[Path, Path]:
    """The in-distribution and OOD sets, simulated once and cached under the robofailring cache dir
    (sets of another size than this bench's own are cached in folders named by their size)."""
    root = default_cache_dir() / "bench-quality"
    sizes = (id_episodes, id_successes, ood_episodes, ood_successes)
    own = sizes == (ID_EPISODES, ID_SUCCESSES, OOD_EPISODES, OOD_SUCCESSES)
    suffix = "" if own else "-" + "-".join(map(str, sizes))
    in_dist = GenerateConfig(
        out=root / f"sim-id{suffix}",
        tasks=TASKS,
        episodes=id_episodes,
        success_episodes=id_successes,
        seed=0,
        image_size=IMAGE_SIZE,
        frames=FRAMES,
        workers=workers,
    )
    out_dist = replace(
        in_dist,
        out=root / f"sim-ood{suffix}",
        episodes=ood_episodes,
        success_episodes=ood_successes,
        seed=1000,
        ood=True,
    )
    paths = []
    for label, config in (("ID", in_dist), ("OOD", out_dist)):
        with progress_bar(total=config.total_episodes, desc=f"simulating {label}", unit="episode") as bar:
            paths.append(generate_dataset(config, progress=bar.update))
    return paths[0], paths[1]


DEPLOYED = 2  # OOD success runs per task that join the success memory under the deployment protocol


@dataclass(frozen=True)
class QualityRow:
    encoder: str
    protocol: str
    result: EvaluationResult
    seconds: float


def evaluate_encoder(
    encoder: str,
    in_dist: Path,
    out_dist: Path,
    *,
    alpha: float,
    out: Path,
    cache_dir: Path | None = None,
    success_step: float = DEFAULT_STEP,
) -> list[QualityRow]:
    """ID, OOD and OOD-with-deployment-successes evaluations of one encoder spec, both rules at α."""
    slug = f"{encoder_slug(load_encoder(encoder).identity)}-step{success_step:g}"
    base = EvaluateConfig(
        data=in_dist,
        out=out / slug,
        encoder=encoder,
        target_fpr=alpha,
        memory_out=out / slug / "memory",
        cache_dir=cache_dir,
        name="in-distribution",
        success_step=success_step,
    )
    ood = replace(base, memory=out / slug / "memory", test_data=out_dist, test_split="ood", name="ood")
    protocols = [
        ("ID", base),
        ("OOD", ood),
        (
            f"OOD + {DEPLOYED} deployment successes/task",
            replace(ood, deployment_successes=DEPLOYED, name="ood-deployed"),
        ),
    ]
    rows = []
    for label, config in protocols:
        start = time.perf_counter()
        result = run_evaluation(config)
        write_evaluation(result, config.out)  # <name>.json and .md, e.g. for `robofailring review`
        rows.append(
            QualityRow(f"{encoder} (step {success_step:g})", label, result, time.perf_counter() - start)
        )
    return rows


def _pct(value: float) -> str:
    return "—" if math.isnan(value) else f"{100 * value:5.1f}"


def print_rows(rows: list[QualityRow], alpha: float) -> None:
    print(
        f"\n| encoder | test set | rule | threshold | Recall (%) | FPR (%) | T_s mean (%) | AUC | "
        f"frame-0 success alarms | failures / successes tested |  (α = {alpha:g}, split conformal on ID training successes)"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        for rule in row.result.rules.values():
            print(
                f"| {row.encoder} | {row.protocol} | {rule.rule.name} | {rule.rule.symbol} = {rule.threshold:.4f} | "
                f"{_pct(rule.recall)} | {_pct(rule.fpr)} | {_pct(rule.ts_mean)} | {rule.auc:.3f} | "
                f"{rule.frame0_success_alarms} | {row.result.failures} / {row.result.successes} |"
            )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--encoder", action="append", help="encoder spec (repeatable; default: pixels)")
    parser.add_argument("--alpha", type=float, default=0.05, help="target FPR α of both rules")
    parser.add_argument("--workers", type=int, default=2, help="simulation processes")
    parser.add_argument(
        "--success-step", type=float, action="append", help=f"thinning step(s) (default {DEFAULT_STEP})"
    )
    parser.add_argument("--train-encoder", action="store_true", help="add a trained encoder's rows")
    args = parser.parse_args()
    start = time.perf_counter()
    in_dist, out_dist = datasets(args.workers)
    print(
        f"datasets (cached): {in_dist}, {out_dist} ({time.perf_counter() - start:.0f} s to simulate or find)"
    )
    print(
        f"  {IMAGE_SIZE} px, {FRAMES} frames per episode; ID {ID_EPISODES} episodes per task and failure family, "
        f"{ID_SUCCESSES} successes per task (even episodes train, odd test); OOD {OOD_EPISODES} per family, "
        f"{OOD_SUCCESSES} successes per task"
    )
    out = default_cache_dir() / "bench-quality" / "runs"
    encoders = list(args.encoder or ["pixels"])
    if args.train_encoder:
        started = time.perf_counter()
        trained = train_encoder(
            TrainEncoderConfig(data=in_dist, out=default_cache_dir() / "bench-quality" / "trained-encoder"),
            reuse=True,
        )
        print(
            f"trained encoder {trained}: {time.perf_counter() - started:.0f} s (0 when reused from the cache)"
        )
        encoders.append(f"trained:{trained}")
    rows = []
    for encoder in encoders:
        for step in args.success_step or [DEFAULT_STEP]:
            found = evaluate_encoder(encoder, in_dist, out_dist, alpha=args.alpha, out=out, success_step=step)
            rows += found
            loaded = FailureMemory.load(Path(found[0].result.memory))
            successes = loaded.successes
            print(
                f"{encoder} (step {step:g}): failure memory {len(loaded)} entries; success memory "
                f"{len(successes) if successes else 0} frames kept of {successes.offered if successes else 0}"
            )
    for row in rows:
        print(f"{row.encoder} {row.protocol}: evaluated in {row.seconds:.0f} s")
    print_rows(rows, args.alpha)


if __name__ == "__main__":
    main()
