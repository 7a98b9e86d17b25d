"""Offline probe (numpy only) of per-frame signal features for the signal memory (issue 41): each
candidate feature set is scored as the detector scores the view `signals` (per task, memory of the
train half, z-scored by its successes, paired [½ z₀ ‖ zₜ − z₀ ‖ actions at t, t−2, t−4 ‖ z(t)],
similarity exp(−d²/n), contrast S⁻ − S⁺, shift band and split-conformal γ on the train half's
successes, each left out) on the peer ManiSkill3 set and the embedded set, ID on both halves and OOD
with 2 deployment successes per task in the success memory.

python -m bench.experiments.probe_signal_events [--peer DIR] [--embedded DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench._timing import print_machine

ALPHA = 0.05
START_WEIGHT = 0.5
DEDUPE = False
ONSET_FLOOR = 0
CLIP = False
TOL_SHARE = -0.05  # < 0: a share of the median in-run range (the library's rule); > 0: of the span over runs
LAGS = (0, 2, 4)


@dataclass
class Run:
    episode: str
    task: str
    failure: bool
    onset: int | None
    split: str
    signals: dict[str, np.ndarray]  # name → (T, D)
    names: dict[str, list[str]]
    kinds: dict[str, str]


def load_peer(root: Path, labels: str) -> list[Run]:
    meta = json.loads((root / "signals.json").read_text())
    runs = []
    with (root / labels).open() as handle:
        for row in csv.DictReader(handle):
            with np.load(root / "episodes" / row["episode"] / "signals.npz") as found:
                signals = {k: np.asarray(found[k], np.float64) for k in found.files}
            onset = row["onset_frame"]
            runs.append(
                Run(
                    row["episode"],
                    row["task"],
                    row["outcome"] == "failure",
                    int(onset) if onset else None,
                    row["split"],
                    signals,
                    {k: v["names"] for k, v in meta.items()},
                    {k: v["kind"] for k, v in meta.items()},
                )
            )
    return runs


def load_embedded(root: Path, swap: bool = False) -> list[Run]:
    runs = []
    for folder in ("sim-id", "sim-ood"):
        manifest = json.loads((root / folder / "manifest.json").read_text())
        for episode in manifest["episodes"]:
            described = episode["signals"]["signals"]
            with np.load(root / folder / episode["dir"] / "signals.npz") as found:
                signals = {k: np.asarray(found[k], np.float64) for k in found.files}
            split = episode.get("split") or "ood"
            if folder == "sim-ood":
                split = "ood"
            elif swap:
                split = {"train": "test", "test": "train"}[split]
            runs.append(
                Run(
                    episode["episode"],
                    episode["task"],
                    episode["outcome"] == "failure",
                    episode.get("onset_frame"),
                    split,
                    signals,
                    {k: v["names"] for k, v in described.items()},
                    {k: v["kind"] for k, v in described.items()},
                )
            )
    return runs


# ---- feature sets: run → (state (T, Ds), action (T, Da)), causal ----

Features = Callable[[Run], tuple[np.ndarray, np.ndarray]]


def pick(run: Run, name: str, dims: list[str] | None = None) -> np.ndarray:
    values = run.signals[name]
    if dims is None:
        return values
    return values[:, [run.names[name].index(d) for d in dims]]


def delta(values: np.ndarray) -> np.ndarray:
    """x_t − x_{t−1} (0 at t = 0)."""
    return np.concatenate([np.zeros_like(values[:1]), np.diff(values, axis=0)])


def since_change(values: np.ndarray, threshold: np.ndarray) -> np.ndarray:
    """Frames since each dimension last changed by more than `threshold` in one frame (t where never)."""
    moved = np.abs(delta(values)) > threshold
    out = np.zeros_like(values)
    for t in range(len(values)):
        out[t] = np.where(moved[t], 0, (out[t - 1] + 1) if t else 0)
    return out


def changes(values: np.ndarray, threshold: np.ndarray) -> np.ndarray:
    """How many times each dimension has changed by more than `threshold` in one frame so far."""
    return np.cumsum(np.abs(delta(values)) > threshold, axis=0).astype(np.float64)


def at_last_change(values: np.ndarray, trigger: np.ndarray, threshold: float) -> np.ndarray:
    """`values` (T, D) held from the last frame where `trigger` (T,) changed by more than `threshold`
    (the start value before any change)."""
    moved = np.abs(delta(trigger[:, None]))[:, 0] > threshold
    out = np.zeros_like(values)
    held = values[0]
    for t in range(len(values)):
        if moved[t]:
            held = values[t]
        out[t] = held
    return out


def running_extremes(values: np.ndarray) -> np.ndarray:
    return np.concatenate([np.minimum.accumulate(values), np.maximum.accumulate(values)], axis=1)


def chosen(run: Run) -> tuple[np.ndarray, np.ndarray]:
    """The peer's CHOSEN dims (width, ee_to_goal | gripper command); the embedded set: width | gripper."""
    if "ee_to_goal" in run.signals:
        return np.concatenate([pick(run, "gripper_width"), pick(run, "ee_to_goal")], 1), pick(
            run, "action", ["gripper"]
        )
    return pick(run, "gripper_width"), pick(run, "action", ["gripper_width"])


def all_dims(run: Run) -> tuple[np.ndarray, np.ndarray]:
    state = [v for k, v in run.signals.items() if run.kinds[k] == "state"]
    action = [v for k, v in run.signals.items() if run.kinds[k] == "action"]
    return np.concatenate(state, 1), np.concatenate(action, 1)


def gripper_of(run: Run) -> tuple[np.ndarray, np.ndarray]:
    """(width (T,), command (T,))."""
    command = "gripper" if "gripper" in run.names["action"] else "gripper_width"
    return pick(run, "gripper_width")[:, 0], pick(run, "action", [command])[:, 0]


def with_derived(base: Features, *parts: str, gate: float = 0.01) -> Features:
    """`base` with derived state dimensions: `delta` (Δ of every base dim), `since` (frames since the
    gripper command / width last changed), `count` (how many such changes), `held` (the base state
    at the last command change), `extremes` (running min and max of the base state)."""

    def features(run: Run) -> tuple[np.ndarray, np.ndarray]:
        state, action = base(run)
        width, command = gripper_of(run)
        grip = np.stack([width, command], 1)
        extra = []
        for part in parts:
            if part == "delta":
                extra.append(delta(np.concatenate([state, action], 1)))
            elif part == "dstate":
                extra.append(delta(state))
            elif part == "since":
                extra.append(since_change(grip, np.full(2, gate)))
            elif part == "count":
                extra.append(changes(grip, np.full(2, gate)))
            elif part == "held":
                extra.append(at_last_change(state, command, gate))
            elif part == "extremes":
                extra.append(running_extremes(state))
            elif part == "wdelta":
                extra.append(delta(width[:, None]))
            else:
                raise ValueError(part)
        return np.concatenate([state, *extra], 1), action

    return features


# ---- the detector, in spirit ----


@dataclass
class TaskMemory:
    mean: np.ndarray
    scale: np.ndarray
    widths: tuple[int, int]
    failure: np.ndarray
    failure_episode: np.ndarray
    success: np.ndarray
    success_episode: np.ndarray


def vectors_of(raw: np.ndarray, mean: np.ndarray, scale: np.ndarray, widths: tuple[int, int]) -> np.ndarray:
    z = (raw - mean) / scale
    sw, aw = widths
    at = np.arange(len(raw))
    lagged = [z[np.maximum(at - lag, 0), sw : sw + aw] for lag in LAGS]
    start = np.broadcast_to(START_WEIGHT * z[0, :sw], (len(raw), sw))
    return np.concatenate([start, z[:, :sw] - z[0, :sw], *lagged, z[:, -1:]], 1)


def raw_of(run: Run, features: Features) -> tuple[np.ndarray, tuple[int, int]]:
    state, action = features(run)
    t = np.arange(len(state), dtype=np.float64)[:, None]
    return np.concatenate([state, action, t], 1), (state.shape[1], action.shape[1])


def build(runs: list[Run], features: Features, extra_successes: list[Run] = ()) -> TaskMemory:  # type: ignore[assignment]
    raws = {r.episode: raw_of(r, features) for r in [*runs, *extra_successes]}
    normal = np.concatenate([raws[r.episode][0] for r in runs if not r.failure])
    mean, scale = normal.mean(0), np.maximum(normal.std(0), 1e-3)
    widths = raws[runs[0].episode][1]
    fail, fail_ep, succ, succ_ep = [], [], [], []
    for r in [*runs, *extra_successes]:
        v = vectors_of(raws[r.episode][0], mean, scale, widths)
        if r.failure:
            start = max(r.onset, ONSET_FLOOR) if r.onset is not None else 1
            fail.append(v[start:])
            fail_ep += [r.episode] * len(v[start:])
        else:
            succ.append(v)
            succ_ep += [r.episode] * len(v)
    failure, failure_episode, success = np.concatenate(fail), np.asarray(fail_ep), np.concatenate(succ)
    if DEDUPE:  # failure entries a success entry coincides with are no evidence
        d2 = ((failure[:, None, :] - success[None, :, :]) ** 2).sum(-1).min(1)
        keep = d2 > 1e-9
        failure, failure_episode = failure[keep], failure_episode[keep]
    return TaskMemory(mean, scale, widths, failure, failure_episode, success, np.asarray(succ_ep))


def nearest(
    vectors: np.ndarray, entries: np.ndarray, entry_episode: np.ndarray, exclude: str | None
) -> np.ndarray:
    keep = entry_episode != exclude
    d2 = ((vectors[:, None, :] - entries[None, keep, :]) ** 2).sum(-1)
    return np.exp(-d2.min(1) / vectors.shape[1])


def contrast(run: Run, memory: TaskMemory, features: Features, exclude: str | None = None) -> np.ndarray:
    raw, _ = raw_of(run, features)
    v = vectors_of(raw, memory.mean, memory.scale, memory.widths)
    found = nearest(v, memory.failure, memory.failure_episode, exclude) - nearest(
        v, memory.success, memory.success_episode, exclude
    )
    return np.maximum(found, 0.0) if CLIP else found


def auc(pos: np.ndarray, neg: np.ndarray) -> float:
    pos, neg = np.asarray(pos)[:, None], np.asarray(neg)[None, :]
    return float(((pos > neg).sum() + 0.5 * (pos == neg).sum()) / (pos.size * neg.size))


def best_recall(pos: np.ndarray, neg: np.ndarray, fpr: float) -> float:
    """The best recall any threshold reaches on the test set at test FPR ≤ fpr (an oracle)."""
    best = 0.0
    for threshold in np.concatenate([pos, neg, [np.inf]]):
        if (neg >= threshold).mean() <= fpr:
            best = max(best, float((pos >= threshold).mean()))
    return best


def band_shift(series: list[np.ndarray]) -> np.ndarray:
    table = np.full((len(series), max(len(s) for s in series)), np.nan)
    for i, s in enumerate(series):
        table[i, : len(s)] = s
    return np.nanmean(table, 0)


@dataclass
class Cell:
    recall: float
    fpr: float
    auc: float
    best: float
    tested: tuple[int, int]
    ts: float


def evaluate(
    runs: list[Run], features: Features, test_split: str, deployed: int = 0, band: bool = True
) -> Cell:
    train = [r for r in runs if r.split == "train"]
    test = [r for r in runs if r.split == test_split]
    if hasattr(features, "base"):
        STEP.clear()
        fit_steps(runs, features.base)
    extra: dict[str, list[Run]] = {}
    if deployed:
        for task in sorted({r.task for r in test}):
            chosen_runs = sorted(
                (r for r in test if r.task == task and not r.failure), key=lambda r: r.episode
            )
            extra[task] = chosen_runs[:deployed]
        moved = {r.episode for rs in extra.values() for r in rs}
        test = [r for r in test if r.episode not in moved]
    memories = {
        task: build([r for r in train if r.task == task], features, extra.get(task, []))
        for task in sorted({r.task for r in train})
    }
    calibration = [contrast(r, memories[r.task], features, r.episode) for r in train if not r.failure]
    if band:
        peaks = []
        for i, s in enumerate(calibration):
            mean = band_shift([c for j, c in enumerate(calibration) if j != i])
            peaks.append(float(np.max(s - mean[np.minimum(np.arange(len(s)), len(mean) - 1)])))
        full = band_shift(calibration)
    else:
        peaks = [float(np.max(s)) for s in calibration]
        full = np.zeros(1)
    ordered = np.sort(peaks)
    rank = math.ceil((len(ordered) + 1) * (1 - ALPHA) - 1e-9)
    gamma = float(np.nextafter(ordered[min(rank, len(ordered)) - 1], np.inf))
    scores, alarms, ts = [], [], []
    for r in test:
        s = contrast(r, memories[r.task], features)
        corrected = s - full[np.minimum(np.arange(len(s)), len(full) - 1)]
        scores.append(float(corrected.max()))
        fired = np.nonzero(corrected >= gamma)[0]
        alarms.append(len(fired) > 0)
        if r.failure and len(fired):
            ts.append(1 - fired[0] / len(s))
    is_failure = np.asarray([r.failure for r in test])
    scores_a, alarms_a = np.asarray(scores), np.asarray(alarms)
    return Cell(
        recall=100 * alarms_a[is_failure].mean(),
        fpr=100 * alarms_a[~is_failure].mean(),
        auc=auc(scores_a[is_failure], scores_a[~is_failure]),
        best=100 * best_recall(scores_a[is_failure], scores_a[~is_failure], 0.05),
        tested=(int(is_failure.sum()), int((~is_failure).sum())),
        ts=100 * float(np.mean(ts)) if ts else float("nan"),
    )


CANDIDATES: dict[str, Features] = {
    "chosen": chosen,
    "all": all_dims,
    "chosen+delta": with_derived(chosen, "delta"),
    "chosen+dstate": with_derived(chosen, "dstate"),
    "chosen+since": with_derived(chosen, "since"),
    "chosen+count": with_derived(chosen, "count"),
    "chosen+held": with_derived(chosen, "held"),
    "chosen+extremes": with_derived(chosen, "extremes"),
    "chosen+since+count": with_derived(chosen, "since", "count"),
    "chosen+since+held": with_derived(chosen, "since", "held"),
    "chosen+delta+since": with_derived(chosen, "delta", "since"),
    "chosen+since+count+held": with_derived(chosen, "since", "count", "held"),
    "all+delta": with_derived(all_dims, "delta"),
    "all+since+count": with_derived(all_dims, "since", "count"),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--peer", type=Path, default=Path.home() / ".cache/robofailring/bench-peer/f4b253f388bf"
    )
    parser.add_argument("--embedded", type=Path, default=None, help="a bench-quality cache folder")
    parser.add_argument("--only", nargs="*", default=None, help="candidate names")
    parser.add_argument("--no-band", action="store_true")
    parser.add_argument("--no-peer", action="store_true")
    parser.add_argument("--dedupe", action="store_true")
    parser.add_argument("--clip", action="store_true")
    parser.add_argument("--onset-floor", type=int, default=0)
    parser.add_argument("--start-weight", type=float, default=0.5)
    args = parser.parse_args()
    print_machine()
    global START_WEIGHT, DEDUPE, ONSET_FLOOR, CLIP
    CLIP = args.clip
    START_WEIGHT, DEDUPE, ONSET_FLOOR = args.start_weight, args.dedupe, args.onset_floor
    sets: dict[str, tuple[list[Run], list[Run]]] = {}
    if not args.no_peer:
        sets["peer"] = (load_peer(args.peer, "labels.csv"), load_peer(args.peer, "labels-swapped.csv"))
    if args.embedded is not None:
        sets["embedded"] = (load_embedded(args.embedded), load_embedded(args.embedded, swap=True))
    names = args.only or list(CANDIDATES)
    print("set | features | ID: recall / FPR (AUC, best@5%) | swapped | OOD + 2 deployed | T_s ID")
    for label, (runs, swapped) in sets.items():
        for name in names:
            features = CANDIDATES[name]
            cells = [
                evaluate(runs, features, "test", band=not args.no_band),
                evaluate(swapped, features, "test", band=not args.no_band),
                evaluate(runs, features, "ood", deployed=2, band=not args.no_band),
            ]
            text = " | ".join(f"{c.recall:.1f} / {c.fpr:.1f} ({c.auc:.3f}, {c.best:.1f})" for c in cells)
            print(f"{label} | {name} | {text} | {cells[0].ts:.1f}", flush=True)


def width_command(run: Run) -> tuple[np.ndarray, np.ndarray]:
    width, command = gripper_of(run)
    return width[:, None], command[:, None]


def goal_offset(run: Run) -> tuple[np.ndarray, np.ndarray]:
    state, action = chosen(run)
    return state[:, 1:] if state.shape[1] > 1 else state, action


def general(base: Features, kinds: tuple[str, ...]) -> Features:
    """The library form: `change` (Δ of every dimension) and `events` (count of changes and frames since
    the last one of every dimension that moves in at most a quarter of the success runs' frames), the
    step-like dimensions chosen per task from its training successes (set by `build`)."""

    def features(run: Run) -> tuple[np.ndarray, np.ndarray]:
        state, action = base(run)
        raw = np.concatenate([state, action], 1)
        mask, tol = STEP[run.task]
        d = delta(raw)
        parts = [state]
        if "change" in kinds:
            parts.append(d)
        if "events" in kinds and mask.any():
            moved = np.abs(d[:, mask]) > tol[mask]
            at = np.arange(len(raw))[:, None]
            parts += [
                np.cumsum(moved, 0).astype(float),
                at - np.maximum.accumulate(np.where(moved, at, 0), 0),
            ]
        return np.concatenate(parts, 1), action

    features.base = base  # type: ignore[attr-defined]
    return features


STEP: dict[str, tuple[np.ndarray, np.ndarray]] = {}


def fit_steps(runs: list[Run], base: Features) -> None:
    for task in {r.task for r in runs}:
        rows = [
            np.concatenate(base(r), 1)
            for r in runs
            if r.task == task and not r.failure and r.split == "train"
        ]
        stacked = np.concatenate(rows)
        span = stacked.max(0) - stacked.min(0)
        if TOL_SHARE < 0:  # a share of the runs' own range (median over the successes)
            tol = -TOL_SHARE * np.median([r.max(0) - r.min(0) for r in rows], axis=0)
        else:
            tol = TOL_SHARE * span
        share = np.concatenate([np.abs(np.diff(r, axis=0)) > tol for r in rows]).mean(0)
        STEP[task] = ((span > 0) & (share > 0) & (share <= 0.25), tol)


CANDIDATES |= {
    "chosen:change": general(chosen, ("change",)),
    "chosen:events": general(chosen, ("events",)),
    "chosen:change,events": general(chosen, ("change", "events")),
    "all:change": general(all_dims, ("change",)),
    "all:events": general(all_dims, ("events",)),
    "all:change,events": general(all_dims, ("change", "events")),
    "grip": width_command,
    "grip+since+count": with_derived(width_command, "since", "count"),
    "grip+delta+since+count": with_derived(width_command, "delta", "since", "count"),
    "chosen+delta+since+count": with_derived(chosen, "delta", "since", "count"),
    "chosen+wdelta+since+count": with_derived(chosen, "wdelta", "since", "count"),
}


if __name__ == "__main__":
    main()
