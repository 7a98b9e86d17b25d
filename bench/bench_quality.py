"""Detection quality: every scoring rule at one α on simulated sets (cached under the robofailring
cache dir), on both halves of the in-distribution split and out of distribution with and without
deployment successes, with the counts each figure rests on.

Run: .venv/bin/python -m bench.bench_quality [--encoder SPEC]... [--alpha 0.05] [--success-step S]...
     [--train-encoder] [--variant LABEL:FIELD=VALUE,...]...

Cells, per encoder and variant (the issue-21 protocol: one lucky split cannot carry a claim):
- `ID`: memory and calibration from the ID set's `train` half, tested on its `test` half;
- `ID swapped`: the halves exchanged (memory and calibration from `test`, tested on `train`);
- `OOD`: the ID `train` memory and thresholds, tested on the OOD set;
- `OOD + 2 deployment successes/task`: the same, with 2 OOD success runs per task moved into the
  success memory (and out of the test set).

Every row says which failure memory it used (`dense` by default, `end`: the paper's).
Each encoder spec is one more block of rows (e.g. `--encoder pixels --encoder trained:DIR`);
`--train-encoder` trains one encoder per ID half (cached), so the swapped cell's encoder never saw
the frames it is tested on; a `trained:DIR` given with `--encoder` was trained on one half only, so
its swapped cell is left out (said in the output). Each `--success-step` (success-frame thinning,
0 = every frame) and each `--variant` (fields of `EvaluateConfig`, e.g.
`--variant dense:failure_frames=dense`) is one more block per encoder.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from bench._timing import print_machine
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.config import Scoring
from robofailring.encoders import default_cache_dir, encoder_slug, load_encoder
from robofailring.encoders.placement import EncoderPlacement
from robofailring.encoders.training import TrainEncoderConfig, train_encoder
from robofailring.evaluation.job import EvaluateConfig, run_evaluation
from robofailring.evaluation.result import EvaluationResult
from robofailring.evaluation.written import write_evaluation
from robofailring.memory.failure import FailureMemory
from robofailring.memory.recipe import MemoryRecipe
from robofailring.memory.thinning import DEFAULT_STEP
from robofailring.sim import TASKS, GenerateConfig, simulate

IMAGE_SIZE = 64
FRAMES = 28
ID_EPISODES = 8  # per task and failure family: 4 tasks x 7 families x 8 = 224 failures, half tested
ID_SUCCESSES = 26  # per task: 104 successes, 52 train (calibration) and 52 test
OOD_EPISODES = 2  # per task and failure family, all tested
OOD_SUCCESSES = 8  # per task: 2 join the success memory under the deployment protocol, 6 tested
DEPLOYED = 2  # OOD success runs per task that join the success memory under the deployment protocol
SWAPPED = "swapped"  # the ID set with its halves exchanged, beside it in the cache


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
    return simulate(in_dist, label="ID"), simulate(out_dist, label="OOD")


def bench_sets(workers: int) -> tuple[Path, Path, Path]:
    """The ID, OOD and ID-halves-swapped sets (simulated once, then found), printed with their sizes."""
    start = time.perf_counter()
    in_dist, out_dist = datasets(workers)
    swapped = swapped_halves(in_dist)
    print(
        f"datasets (cached): {in_dist}, {out_dist}, {swapped} ({time.perf_counter() - start:.0f} s to simulate or find)"
    )
    print(
        f"  {IMAGE_SIZE} px, {FRAMES} frames per episode; ID {ID_EPISODES} episodes per task and failure family, "
        f"{ID_SUCCESSES} successes per task (even episodes one half, odd the other); OOD {OOD_EPISODES} per family, "
        f"{OOD_SUCCESSES} successes per task"
    )
    return in_dist, out_dist, swapped


def swapped_halves(in_dist: Path) -> Path:
    """The ID set with its `train` and `test` halves exchanged: a folder beside it holding a copy of
    its manifest with the two split names swapped and a link to each episode folder (no frame copied)."""
    manifest = json.loads((in_dist / "manifest.json").read_text(encoding="utf-8"))
    exchange = {"train": "test", "test": "train"}
    for record in manifest["episodes"]:
        record["split"] = exchange.get(record.get("split"), record.get("split"))
    out = in_dist.with_name(f"{in_dist.name}-{SWAPPED}")
    out.mkdir(exist_ok=True)
    for record in manifest["episodes"]:
        link = out / record["dir"]
        if not link.is_symlink():
            link.symlink_to((in_dist / record["dir"]).resolve(), target_is_directory=True)
    staged = out / "manifest.json.tmp"
    staged.write_text(json.dumps(manifest, indent=1), encoding="utf-8")
    staged.replace(out / "manifest.json")
    return out


@dataclass(frozen=True)
class Variant:
    """One block of rows: a label and the `EvaluateConfig` fields it sets."""

    label: str
    settings: dict[str, Any]

    @staticmethod
    def parse(text: str) -> Variant:
        """`LABEL:field=value,field=value` (numbers are read as numbers, true/false/null as such, the rest as
        text); a field of `EvaluateConfig`, of its `MemoryRecipe` (e.g. `signals=none`) or of its
        `Scoring` or `EncoderPlacement` (e.g. `modality=signals`)."""
        label, _, body = text.partition(":")
        known = {
            f.name
            for kind in (EvaluateConfig, MemoryRecipe, Scoring, EncoderPlacement, ThresholdPolicy)
            for f in fields(kind)
        }
        settings: dict[str, Any] = {}
        for item in filter(None, body.split(",")):
            name, sep, value = item.partition("=")
            if not sep or name not in known:
                raise SystemExit(
                    f"--variant {text!r}: {item!r} is not FIELD=VALUE with a field of EvaluateConfig, MemoryRecipe, "
                    "Scoring, EncoderPlacement or ThresholdPolicy"
                )
            settings[name] = _value(value)
        return Variant(label or "default", settings)


def with_variant(config: EvaluateConfig, variant: Variant) -> EvaluateConfig:
    """`config` with the variant's settings, each in the value it belongs to (the recipe, the detector's
    config, the threshold policy, or the evaluation's own)."""
    recipe_fields = {f.name for f in fields(MemoryRecipe)}
    policy_fields = {f.name for f in fields(ThresholdPolicy)}
    scoring_fields = {f.name for f in fields(Scoring)}
    placement_fields = {f.name for f in fields(EncoderPlacement)}
    settings = variant.settings
    policy = config.threshold_policy
    if policy is not None:
        policy = replace(policy, **{k: v for k, v in settings.items() if k in policy_fields})
    return replace(
        config,
        recipe=replace(config.recipe, **{k: v for k, v in settings.items() if k in recipe_fields}),
        scoring=replace(config.scoring, **{k: v for k, v in settings.items() if k in scoring_fields}),
        placement=replace(config.placement, **{k: v for k, v in settings.items() if k in placement_fields}),
        threshold_policy=policy,
        **{
            k: v
            for k, v in settings.items()
            if k not in recipe_fields | scoring_fields | placement_fields | policy_fields
        },
    )


def _value(text: str) -> Any:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {"true": True, "false": False, "null": None}.get(text.lower(), text)


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
    swapped: tuple[Path, str] | None,
    cache_dir: Path | None = None,
    success_step: float = DEFAULT_STEP,
    variant: Variant = Variant("default", {}),
) -> list[QualityRow]:
    """The four cells of one encoder spec and variant, every rule at α; `swapped`: the halves-swapped
    set and the encoder to judge it with (None: the cell is left out)."""
    slug = f"{encoder_slug(load_encoder(encoder).identity)}-step{success_step:g}-{variant.label}"
    name = f"{encoder} (step {success_step:g}, {variant.label})"
    base = EvaluateConfig(
        data=DataSelection(in_dist),
        recipe=MemoryRecipe(encoder=encoder, success_step=success_step),
        placement=EncoderPlacement(cache_dir=cache_dir),
        out=out / slug,
        threshold_policy=ThresholdPolicy(alpha),
        memory_out=out / slug / "memory",
        name="in-distribution",
    )
    base = with_variant(base, variant)
    ood = replace(
        base,
        memory=out / slug / "memory",
        test_data=base.data.other(out_dist),
        test_split="ood",
        name="ood",
    )
    in_swapped = None
    if swapped is not None:
        data, spec = swapped
        in_swapped = replace(
            base,
            data=base.data.other(data),
            recipe=replace(base.recipe, encoder=spec),
            out=out / f"{slug}-swapped",
            memory_out=out / f"{slug}-swapped" / "memory",
            name="in-distribution-swapped",
        )
    return [
        QualityRow(name, label, result, seconds)
        for label, _, result, seconds in run_cells(base, swapped=in_swapped, ood=ood)
    ]


def run_cells(
    base: EvaluateConfig, *, swapped: EvaluateConfig | None, ood: EvaluateConfig
) -> list[tuple[str, EvaluateConfig, EvaluationResult, float]]:
    """The cells of one encoder and variant, each evaluated and written (<name>.json and .md, e.g. for
    `robofailring review`): ID, ID swapped (when given), OOD, and OOD with DEPLOYED deployment
    successes per task; per cell its label, config, result and seconds."""
    cells = [("ID", base), *([("ID swapped", swapped)] if swapped is not None else []), ("OOD", ood)]
    cells.append(
        (
            f"OOD + {DEPLOYED} deployment successes/task",
            replace(ood, deployment_successes=DEPLOYED, name="ood-deployed"),
        )
    )
    found = []
    for label, config in cells:
        start = time.perf_counter()
        result = run_evaluation(config)
        write_evaluation(result, config.out)
        found.append((label, config, result, time.perf_counter() - start))
    return found


def _pct(value: float) -> str:
    return "—" if math.isnan(value) else f"{100 * value:5.1f}"


def _onset(rule: Any) -> str:
    onset = rule.onset
    if onset is None or not onset.known:
        return "—"
    median = "—" if math.isnan(onset.median_frames) else f"{onset.median_frames:.0f}"
    return f"{median} / {onset.premature}"


def print_rows(rows: list[QualityRow], alpha: float) -> None:
    print(
        f"\n| encoder | failure memory | test set | rule | threshold | Recall (%) | FPR (%) | T_s mean (%) | AUC | "
        f"delay after onset, median frames / premature | frame-0 success alarms | failures / successes tested |"
        f"  (α = {alpha:g}, split conformal on the memory half's successes)"
    )
    print("|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        for rule in row.result.rules.values():
            print(
                f"| {row.encoder} | {row.result.failure_frames}, {row.result.pairing} | {row.protocol} | {rule.rule.name} | {rule.rule.symbol} = {rule.threshold:.4f} | "
                f"{_pct(rule.recall)} | {_pct(rule.fpr)} | {_pct(rule.ts_mean)} | {rule.auc:.3f} | {_onset(rule)} | "
                f"{rule.frame0_success_alarms} | {row.result.failures} / {row.result.successes} |"
            )


def print_modalities(rows: list[QualityRow], rule: str = "contrast") -> None:
    """`rule` per modality in every cell (the cameras alone, the signals alone, both; each at its own calibrated
    threshold) with recall per failure family (detected / total): which families each modality can see at all."""
    kinds = sorted(
        {
            kind
            for row in rows
            for found in row.result.modalities.get(rule, {}).values()
            for kind in found.per_type
        }
    )
    print(
        f"\n| encoder | test set | modality | threshold | Recall (%) | FPR (%) | best recall at that FPR (%) | "
        f"T_s mean (%) | AUC | {' | '.join(kinds)} |  ({rule} rule, per modality)"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|---:|" + "---:|" * len(kinds))
    for row in rows:
        for modality, found in row.result.modalities.get(rule, {}).items():
            result = found.result
            families = [
                f"{found.per_type[k][0]} / {found.per_type[k][1]}" if k in found.per_type else "—"
                for k in kinds
            ]
            print(
                f"| {row.encoder} | {row.protocol} | {modality} | {result.threshold:.4f} | {_pct(result.recall)} | "
                f"{_pct(result.fpr)} | {_pct(result.best_recall)} | {_pct(result.ts_mean)} | {result.auc:.3f} | "
                + " | ".join(families)
                + " |"
            )


def _trained(data: Path, out: Path) -> str:
    started = time.perf_counter()
    trained = train_encoder(TrainEncoderConfig(data=data, out=out), reuse=True)
    print(
        f"trained encoder {trained} on {data.name}'s train half: {time.perf_counter() - started:.0f} s (0: cached)"
    )
    return f"trained:{trained}"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--encoder", action="append", help="encoder spec (repeatable; default: pixels)")
    parser.add_argument("--alpha", type=float, default=0.05, help="target FPR α of every rule")
    parser.add_argument("--workers", type=int, default=2, help="simulation processes")
    parser.add_argument(
        "--success-step", type=float, action="append", help=f"thinning step(s) (default {DEFAULT_STEP})"
    )
    parser.add_argument(
        "--train-encoder", action="store_true", help="add a trained encoder's rows (one per half)"
    )
    parser.add_argument(
        "--variant",
        action="append",
        type=Variant.parse,
        help="LABEL:FIELD=VALUE,... of EvaluateConfig (repeatable)",
    )
    args = parser.parse_args()
    print_machine()
    in_dist, out_dist, swapped = bench_sets(args.workers)
    out = default_cache_dir() / "bench-quality" / "runs"
    pairs: list[tuple[str, str | None]] = []  # (encoder, the swapped cell's encoder or None)
    for spec in args.encoder or ["pixels"]:
        untrained = not spec.startswith("trained:")
        pairs.append((spec, spec if untrained else None))
        if not untrained:
            print(
                f"{spec}: trained on one half only, so its 'ID swapped' cell is left out (use --train-encoder)"
            )
    if args.train_encoder:
        cache = default_cache_dir() / "bench-quality"
        pairs.append(
            (
                _trained(in_dist, cache / "trained-encoder"),
                _trained(swapped, cache / "trained-encoder-swapped"),
            )
        )
    rows = []
    for encoder, swapped_encoder in pairs:
        for step in args.success_step or [DEFAULT_STEP]:
            for variant in args.variant or [Variant("default", {})]:
                found = evaluate_encoder(
                    encoder,
                    in_dist,
                    out_dist,
                    alpha=args.alpha,
                    out=out,
                    swapped=None if swapped_encoder is None else (swapped, swapped_encoder),
                    success_step=step,
                    variant=variant,
                )
                rows += found
                loaded = FailureMemory.load(Path(found[0].result.memory))
                successes = loaded.successes
                print(
                    f"{found[0].encoder}: {loaded.manifest.failure_mode} failure memory {len(loaded)} entries; success memory "
                    f"{len(successes) if successes else 0} frames kept of {successes.offered if successes else 0}"
                )
    for row in rows:
        print(f"{row.encoder} {row.protocol}: evaluated in {row.seconds:.0f} s")
    print_rows(rows, args.alpha)
    print_modalities(rows)


if __name__ == "__main__":
    main()
