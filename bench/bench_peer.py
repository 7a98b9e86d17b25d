"""Detection quality on a peer's simulator: a FailGen-style set made with ManiSkill3, read back as a
user's data (image-episode folders and a labels file), every encoder and scoring rule at one α.

Run: .venv/bin/python -m bench.bench_peer [--train-encoder] [--randomize N] [--encoder SPEC]... [--alpha 0.05]
     [--peer-env DIR]

The set (docs/bench_peer.md): 3 ManiSkill3 tasks (PickCube, StackCube, PushCube), the Panda with its
hand camera plus the task's sensor and render cameras, a motion-planned script with FailGen's
failures injected at one waypoint, the outcome decided by the environment's own success check and
the onset recorded; an in-distribution set and an out-of-distribution one (ManiSkill's lighting,
colour and camera randomisation). `bench/peer_generate.py` simulates it in the bench-only venv
that `bench/setup_peer.sh` makes (run here when that venv is not ready; never the project's .venv),
and it is cached under the robofailring cache dir by its recipe (generator source, requirements,
sizes, seeds). It is then one root of episode folders with three labels files naming each
episode's task, outcome, symbol, onset and split: `labels.csv` (ID halves `train`/`test`, the OOD
set `ood`), `labels-swapped.csv` (the halves exchanged). The cells are bench_quality.py's:
`ID`, `ID swapped`, `OOD`, `OOD + 2 deployment successes/task`, each through `run_evaluation`, once with the project's defaults
and once with `fusion=per-view` (each view corrected by a band of its own before the max).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import shutil
import subprocess
import time
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from bench._peer_lerobot import STATES, export_lerobot
from bench._timing import print_machine
from bench.bench_quality import QualityRow, Variant, print_modalities, print_rows, run_cells, with_variant
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.encoders import default_cache_dir, encoder_slug, load_encoder
from robofailring.encoders.training import TrainEncoderConfig, train_encoder
from robofailring.evaluation.job import EvaluateConfig
from robofailring.memory.recipe import MemoryRecipe

HERE = Path(__file__).resolve().parent
FPS = 10  # the LeRobot export's frame rate (the frames are picked evenly from each run's steps)
GENERATOR = HERE / "peer_generate.py"
SETUP = HERE / "setup_peer.sh"
REQUIREMENTS = HERE / "requirements-peer.txt"
# per task: 4 episodes of each failure family and 24 unperturbed runs (even index: train, odd: test): 12 per
# task and half, so that a half's calibration successes (about 40 with the survived runs) exceed the 39 at
# which split conformal at α = 0.05 stops taking the highest one
ID_SET: dict[str, Any] = {"episodes": 4, "successes": 24, "seed": 0, "size": 64, "frames": 28}
# per task: 2 episodes of each failure family, 8 unperturbed runs (2 join the success memory under
# the deployment protocol), ManiSkill's randomisation of lighting, colours and cameras
OOD_SET: dict[str, Any] = {
    "episodes": 2,
    "successes": 8,
    "seed": 500_000,
    "size": 64,
    "frames": 28,
    "ood": True,
}
# `--randomize N`: N episodes per task and failure family and 4N unperturbed runs per task under the
# OOD randomisation (its own seeds), the trained encoder's extra training data only (never memory,
# calibration or test)
RANDOM_SET: dict[str, Any] = {"seed": 900_000, "size": 64, "frames": 28, "ood": True}
# the project's defaults: cameras and signals fused (each alone beside it, per modality)
BOTH = Variant("both", {})
# dimensions chosen by hand (docs/bench_peer.md), per state: the privileged set's gripper and the hand's offset
# from the task's goal (which no robot records); the recorded set's gripper only (the docs' advice before the
# defaults chose from the data)
CHOSEN: dict[str, str] = {
    "privileged": "observation.state:gripper_width.*,observation.state:ee_to_goal.*,action:gripper",
    "recorded": "observation.state:gripper_width.*,observation.state:joint_positions.finger_*,action:gripper",
}


def chosen(state: str) -> Variant:
    """The defaults with the hand-chosen dimensions of `state` in place of those chosen from the data."""
    return Variant("chosen", {"signals": CHOSEN[state]})


PER_VIEW = Variant("per-view", {"fusion": "per-view"})  # each view corrected by its own band
LABEL_COLUMNS = ("episode", "task", "outcome", "symbol", "onset_frame", "description", "split")


@dataclass(frozen=True)
class PeerRow(QualityRow):
    sweep: tuple[tuple[float, float], ...]  # the contrast rule's (recall, test FPR) at every threshold

    def ceiling(self, fpr: float) -> float:
        """The best recall at a test FPR ≤ `fpr` over every threshold: what any calibration could reach."""
        return max((recall for recall, rate in self.sweep if rate <= fpr), default=float("nan"))


@dataclass(frozen=True)
class PeerSet:
    """The generated set: one root of episode folders and its labels files."""

    root: Path  # episodes/<episode>/<view>/<n>.png and signals.npz (an encoder trains on these)
    labels: Path  # split: train / test (ID halves), ood
    swapped_labels: Path  # the ID halves exchanged
    runs: list[dict[str, Any]]  # per episode: intent, the environment's verdict, split
    lerobot: Path  # the same set as a LeRobot v3.0 dataset (cameras, state, action): what is evaluated
    state: str  # which state it holds (bench/_peer_lerobot.py's STATES)
    lerobot_labels: Path  # its labels by episode_index, split as `labels`
    lerobot_swapped: Path  # and as `swapped_labels`


def default_peer_env() -> Path:
    return Path(os.environ.get("ROBOFAILRING_PEER_ENV", default_cache_dir() / "peer-env"))


def ready_peer_env(env_dir: Path) -> Path:
    """The bench-only venv with Mesa 25, made by setup_peer.sh when it is not ready yet."""
    if not (env_dir / "ready").is_file():
        subprocess.run(["bash", str(SETUP), str(env_dir)], check=True)
    return env_dir


def recipe() -> dict[str, Any]:
    digest = hashlib.sha256(GENERATOR.read_bytes() + REQUIREMENTS.read_bytes()).hexdigest()
    return {"generator_and_requirements": digest, "id": ID_SET, "ood": OOD_SET}


def _generate(env_dir: Path, out: Path, settings: dict[str, Any], workers: int) -> None:
    command = [str(env_dir / "venv" / "bin" / "python"), str(GENERATOR), "--out", str(out)]
    for name, value in settings.items():
        command += [f"--{name}"] if value is True else [f"--{name}", str(value)]
    mesa = env_dir / "mesa" / "usr" / "lib" / "x86_64-linux-gnu"
    env = {
        **os.environ,
        "VK_ICD_FILENAMES": str(env_dir / "lvp_icd.json"),
        "LD_LIBRARY_PATH": ":".join(filter(None, [str(mesa), os.environ.get("LD_LIBRARY_PATH")])),
    }
    subprocess.run([*command, "--workers", str(workers)], check=True, env=env)


def _write_labels(path: Path, rows: list[dict[str, Any]]) -> None:
    with path.open("w", newline="", encoding="utf-8") as file:
        writer = csv.DictWriter(file, fieldnames=LABEL_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def _assemble(staging: Path) -> None:
    """The two generated sets as one root of episode folders (OOD ones named `ood-…`) and its labels files."""
    episodes = staging / "episodes"
    episodes.mkdir()
    runs: list[dict[str, Any]] = []
    for part in ("id", "ood"):
        generated = staging / f"gen-{part}"
        for line in (generated / "runs.jsonl").read_text(encoding="utf-8").splitlines():
            run = json.loads(line)
            name = run["episode"] if part == "id" else f"ood-{run['episode']}"
            (generated / "episodes" / run["episode"]).rename(episodes / name)
            split = "ood" if part == "ood" else ("train" if run["spec"]["index"] % 2 == 0 else "test")
            runs.append({**run, "episode": name, "split": split})
        if part == "id":
            (generated / "signals.json").rename(staging / "signals.json")
        shutil.rmtree(generated)
    exchange = {"train": "test", "test": "train", "ood": "ood"}
    _write_labels(staging / "labels.csv", runs)
    _write_labels(staging / "labels-swapped.csv", [{**r, "split": exchange[r["split"]]} for r in runs])
    with (staging / "runs.jsonl").open("w", encoding="utf-8") as file:
        file.writelines(json.dumps(run) + "\n" for run in runs)


def peer_set(env_dir: Path | None, workers: int, state: str = "recorded") -> PeerSet:
    """The set of this recipe: found in the cache, else simulated (in the peer venv) and cached; its LeRobot
    export holds `state` (what a robot records, or the privileged state with the goal)."""
    wanted = recipe()
    key = hashlib.sha256(json.dumps(wanted, sort_keys=True).encode()).hexdigest()[:12]
    root = default_cache_dir() / "bench-peer" / key
    if not (root / "recipe.json").is_file():
        env_dir = ready_peer_env(env_dir or default_peer_env())
        staging = root.with_name(f"{key}.partial")
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True)
        started = time.perf_counter()
        for part, settings in (("id", ID_SET), ("ood", OOD_SET)):
            _generate(env_dir, staging / f"gen-{part}", settings, workers)
        _assemble(staging)
        (staging / "recipe.json").write_text(json.dumps(wanted, indent=1), encoding="utf-8")
        shutil.rmtree(root, ignore_errors=True)
        staging.rename(root)
        print(f"simulated the peer set in {time.perf_counter() - started:.0f} s")
    runs = [json.loads(line) for line in (root / "runs.jsonl").read_text(encoding="utf-8").splitlines()]
    lerobot = root / f"lerobot-{state}"
    if not (lerobot / "meta" / "info.json").is_file():
        staging = root / f"lerobot-{state}.partial"
        shutil.rmtree(staging, ignore_errors=True)
        started = time.perf_counter()
        described = json.loads((root / "signals.json").read_text(encoding="utf-8"))
        names = {name: list(signal["names"]) for name, signal in described.items()}
        export_lerobot(root / "episodes", runs, staging, fps=FPS, signal_names=names, state=state)
        staging.rename(lerobot)
        print(
            f"wrote the peer set as a LeRobot v3.0 dataset in {time.perf_counter() - started:.0f} s: {lerobot}"
        )
    return PeerSet(
        root / "episodes",
        root / "labels.csv",
        root / "labels-swapped.csv",
        runs,
        lerobot,
        state,
        lerobot / "labels.csv",
        lerobot / "labels-swapped.csv",
    )


def random_look_set(env_dir: Path | None, workers: int, per_family: int) -> Path:
    """Random-look episodes for training only, as AHA-named episode folders (the name says the task and
    the environment's verdict; runs it judged failed with no fault injected are left out)."""
    settings = {**RANDOM_SET, "episodes": per_family, "successes": 4 * per_family}
    wanted = {**recipe(), "random_looks": settings}
    key = hashlib.sha256(json.dumps(wanted, sort_keys=True).encode()).hexdigest()[:12]
    root = default_cache_dir() / "bench-peer" / f"random-looks-{key}"
    if not (root / "recipe.json").is_file():
        env_dir = ready_peer_env(env_dir or default_peer_env())
        staging = root.with_name(f"{root.name}.partial")
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True)
        _generate(env_dir, staging / "gen", settings, workers)
        (staging / "episodes").mkdir()
        for line in (staging / "gen" / "runs.jsonl").read_text(encoding="utf-8").splitlines():
            run = json.loads(line)
            if run["outcome"] == "failure" and not run["symbol"]:
                continue
            kind = run["symbol"] or "success"
            name = f"{run['task']}_{kind}_episode{run['spec']['seed']}"
            (staging / "gen" / "episodes" / run["episode"]).rename(staging / "episodes" / name)
        shutil.rmtree(staging / "gen")
        (staging / "recipe.json").write_text(json.dumps(wanted, indent=1), encoding="utf-8")
        shutil.rmtree(root, ignore_errors=True)
        staging.rename(root)
    return root / "episodes"


def describe(peer: PeerSet) -> None:
    """The set's counts, and how often the environment's verdict differs from the intent."""
    print(f"peer set (cached): {peer.root.parent}; labels {peer.labels.name}, {peer.swapped_labels.name}")
    print(
        f"  ID {ID_SET['episodes']} episodes per task and failure family, {ID_SET['successes']} unperturbed "
        f"per task; OOD {OOD_SET['episodes']} and {OOD_SET['successes']}; {ID_SET['size']} px, "
        f"{ID_SET['frames']} frames, views hand, base, render"
    )
    print(
        "\n| task | split | failures (typed, onset known) | successes | injected, env says success | unperturbed, env says failure |"
    )
    print("|---|---|---:|---:|---:|---:|")
    counts: Counter[tuple[str, str, str]] = Counter()
    for run in peer.runs:
        kind = run["outcome"]
        if run["intent"] != "success" and run["env_success"]:
            kind = "survived"
        elif run["intent"] == "success" and not run["env_success"]:
            kind = "broke"
        counts[(run["task"], run["split"], kind)] += 1
        if run["outcome"] == "failure" and run["symbol"] and run["onset_frame"] != "":
            counts[(run["task"], run["split"], "onset")] += 1
    for task in sorted({run["task"] for run in peer.runs}):
        for split in ("train", "test", "ood"):
            c = {
                kind: counts[(task, split, kind)]
                for kind in ("failure", "onset", "success", "survived", "broke")
            }
            failures = c["failure"] + c["broke"]
            print(
                f"| {task} | {split} | {failures} ({c['onset']}) | {c['success'] + c['survived']} | "
                f"{c['survived']} | {c['broke']} |"
            )


def _sweep(evaluation: Path) -> tuple[tuple[float, float], ...]:
    """From an evaluation's JSON: the contrast rule's (recall, test FPR) over its threshold sweep."""
    sweep = json.loads(evaluation.read_text(encoding="utf-8"))["rules"]["contrast"]["sweep"]
    return tuple((row["recall"], row["fpr"]) for row in sweep)


def evaluate_encoder(
    encoder: str,
    swapped_encoder: str | None,
    peer: PeerSet,
    *,
    alpha: float,
    out: Path,
    variant: Variant = BOTH,
) -> list[PeerRow]:
    """bench_quality's four cells on the peer set: ID, ID swapped (when `swapped_encoder`), OOD, OOD + deployment."""
    slug = encoder_slug(load_encoder(encoder).identity) + f"-{peer.state}-{variant.label}"
    name = f"{encoder} ({peer.state} state, {variant.label})"
    base = EvaluateConfig(
        data=DataSelection(peer.lerobot, labels=peer.lerobot_labels),
        recipe=MemoryRecipe(encoder=encoder),
        out=out / slug,
        threshold_policy=ThresholdPolicy(alpha),
        memory_out=out / slug / "memory",
        name="in-distribution",
    )
    base = with_variant(base, variant)
    swapped = None
    if swapped_encoder is not None:
        swapped = replace(
            base,
            data=replace(base.data, labels=peer.lerobot_swapped),
            recipe=replace(base.recipe, encoder=swapped_encoder),
            out=out / f"{slug}-swapped",
            memory_out=out / f"{slug}-swapped" / "memory",
            name="in-distribution-swapped",
        )
    ood = replace(
        base,
        memory=out / slug / "memory",
        memory_out=None,
        test_split="ood",
        name="ood",
    )
    return [
        PeerRow(name, label, result, seconds, _sweep(Path(config.out) / f"{config.name}.json"))
        for label, config, result, seconds in run_cells(base, swapped=swapped, ood=ood)
    ]


def print_targets(rows: list[PeerRow]) -> None:
    """Issue 51's targets for the contrast rule (ID: recall ≥ 75 % at a test FPR ≤ 10 % and AUC ≥ 0.85 on both
    halves; OOD + deployment successes: ≥ 60 % at ≤ 15 %), met or missed and by how much, beside the rule's best
    recall at the target's test FPR over every threshold (what calibration could reach)."""
    print(
        "\n| encoder | cell | target | recall (%) | FPR (%) | AUC | met | best recall at the target FPR (%) |"
    )
    print("|---|---|---|---:|---:|---:|---|---:|")
    for row in rows:
        rule = row.result.rules.get("contrast")
        if rule is None:
            continue
        if row.protocol.startswith("ID"):
            recall, fpr, auc = 75.0, 10.0, 0.85
        elif "deployment" in row.protocol:
            recall, fpr, auc = 60.0, 15.0, None
        else:
            continue
        misses = [f"recall {100 * rule.recall - recall:+.1f}"] if not 100 * rule.recall >= recall else []
        misses += [f"FPR {100 * rule.fpr - fpr:+.1f}"] if not 100 * rule.fpr <= fpr else []
        if auc is not None and not rule.auc >= auc:
            misses.append(f"AUC {rule.auc - auc:+.3f}")
        target = f"≥ {recall:g} % at ≤ {fpr:g} %" + (f", AUC ≥ {auc:g}" if auc else "")
        print(
            f"| {row.encoder} | {row.protocol} | {target} | {100 * rule.recall:.1f} | {100 * rule.fpr:.1f} | "
            f"{rule.auc:.3f} | {'yes' if not misses else 'no: ' + ', '.join(misses)} | "
            f"{100 * row.ceiling(fpr / 100):.1f} |"
        )


def _trained(peer: PeerSet, labels: Path, out: Path, extra: tuple[Path, ...] = ()) -> str:
    started = time.perf_counter()
    config = TrainEncoderConfig(data=DataSelection(peer.root, labels=labels), out=out, extra_data=extra)
    trained = train_encoder(config, reuse=True)
    print(
        f"trained encoder {trained} on the train half of {labels.name}"
        f"{' + random looks' if extra else ''}: {time.perf_counter() - started:.0f} s"
    )
    return f"trained:{trained}"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--encoder", action="append", help="encoder spec (repeatable; default: pixels)")
    parser.add_argument(
        "--train-encoder", action="store_true", help="add a trained encoder's rows (one per half)"
    )
    parser.add_argument("--alpha", type=float, default=0.05, help="target FPR α of every rule")
    parser.add_argument("--workers", type=int, default=2, help="simulation processes")
    parser.add_argument(
        "--peer-env",
        type=Path,
        default=None,
        help="bench-only venv folder (default: $ROBOFAILRING_PEER_ENV or the cache's peer-env)",
    )
    parser.add_argument(
        "--variant",
        action="append",
        type=Variant.parse,
        help="LABEL:FIELD=VALUE,... of EvaluateConfig, its MemoryRecipe or DetectorConfig, e.g. hand:views=hand "
        "(repeatable; one more block each; default: both, the defaults, and chosen, the dimensions chosen by hand "
        "(CHOSEN); each gives the cameras alone and the signals alone beside both)",
    )
    parser.add_argument(
        "--state",
        action="append",
        choices=sorted(STATES),
        help="the LeRobot export's observation.state (repeatable; default: recorded, then privileged): what a "
        "robot records, or that with the hand's offset from the task's goal",
    )
    parser.add_argument(
        "--randomize",
        type=int,
        default=0,
        help="N: also a trained encoder with N random-look episodes per task and failure family (and 4N "
        "unperturbed per task) as extra training data",
    )
    args = parser.parse_args()
    print_machine()
    states = args.state or ["recorded", "privileged"]
    peer = peer_set(args.peer_env, args.workers, states[0])
    describe(peer)
    cache = peer.root.parent
    pairs: list[tuple[str, str | None]] = [
        (spec, None if spec.startswith("trained:") else spec) for spec in args.encoder or ["pixels"]
    ]
    if args.train_encoder:
        pairs.append(
            (
                _trained(peer, peer.labels, cache / "trained-encoder"),
                _trained(peer, peer.swapped_labels, cache / "trained-encoder-swapped"),
            )
        )
    if args.randomize:
        extra = (random_look_set(args.peer_env, args.workers, args.randomize),)
        suffix = f"random{args.randomize}"
        pairs.append(
            (
                _trained(peer, peer.labels, cache / f"trained-encoder-{suffix}", extra),
                _trained(peer, peer.swapped_labels, cache / f"trained-encoder-{suffix}-swapped", extra),
            )
        )
    rows: list[PeerRow] = []
    for state in states:
        peer = peer_set(args.peer_env, args.workers, state)
        # the defaults' evaluation gives the cameras alone and the signals alone beside both (each calibrated
        # on its own), and so does the one with the dimensions chosen by hand
        variants = args.variant or [BOTH, chosen(state)]
        for encoder, swapped_encoder in pairs:
            for variant in variants:
                rows += evaluate_encoder(
                    encoder, swapped_encoder, peer, alpha=args.alpha, out=cache / "runs", variant=variant
                )
    for row in rows:
        print(f"{row.encoder} {row.protocol}: evaluated in {row.seconds:.0f} s")
    quality: list[QualityRow] = list(rows)
    print_rows(quality, args.alpha)
    print_modalities(quality)
    print_targets(rows)


if __name__ == "__main__":
    main()
