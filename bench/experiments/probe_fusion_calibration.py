"""Offline probe (issue 41, numpy only): ways to fuse and calibrate the camera views and the `signals` view,
on the per-view contrast `probe_fusion_dump.py` dumped, judged as the library judges (split conformal at
α = 0.05 on the calibration runs' peaks, each corrected by a band fitted without it; recall, FPR, T_s and
the AUC of the peak on the test runs). The `max` row reproduces the benches' contrast rows.

Run: .venv/bin/python -m bench.experiments.probe_fusion_calibration DUMP.npz [--only NAME]...

A strategy is channels × band scope × band kind × normalisation:
- channels: `fused` (the max over every view, then one band: the library's `max`), `modality` (the camera
  views' max and `signals`, each its own band), `view` (each view its own band: the library's `per-view`),
  `cameras` / `signals` (one modality alone);
- scope: `pooled` (one band over all tasks), `task` (a band per task where it has ≥ MIN_TASK runs, else the
  pooled one), `task-signals` (per task for the signals only);
- kind: `shift` (μ_t) or `norm` (μ_t, σ_t);
- normalisation of each channel's corrected score before the max: `none`, or `gamma` (divided by that
  channel's own conformal threshold among the other calibration runs: each channel is then as loud at its own
  α, and the fused threshold is set over the max of those), or `offset` (that threshold subtracted instead).
"""

from __future__ import annotations

import argparse
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench._timing import print_machine
from robofailring.calibration.bands import fit_band, leave_one_out
from robofailring.calibration.conformal import conformal_threshold

ALPHA = 0.05
MIN_TASK = int(os.environ.get("MIN_TASK", "10"))


def load(path: Path) -> list[dict[str, Any]]:
    data = np.load(path)
    meta = json.loads(str(data["meta"]))
    by_run: dict[int, dict[str, np.ndarray]] = {}
    for key in data.files:
        if key == "meta":
            continue
        index, view = key.split(":", 1)
        by_run.setdefault(int(index), {})[view] = data[key].astype(np.float64)
    for i, run in enumerate(meta):
        run["scores"] = by_run.get(i, {})
    return meta


def maxed(arrays: list[np.ndarray]) -> np.ndarray:
    stacked = np.stack([np.where(np.isfinite(a), a, -np.inf) for a in arrays])
    top = stacked.max(0)
    return np.where(np.isfinite(top), top, np.nan)


def channels_of(scores: dict[str, np.ndarray], channels: str) -> dict[str, np.ndarray]:
    cameras = [v for k, v in scores.items() if k != "signals"]
    if channels == "fused":
        return {"fused": maxed(list(scores.values()))}
    if channels == "cameras":
        return {"cameras": maxed(cameras)}
    if channels == "signals":
        return {"signals": scores["signals"]}
    if channels == "modality":
        return {"cameras": maxed(cameras), "signals": scores["signals"]}
    return dict(scores)


def peak(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else float("nan")


@dataclass(frozen=True)
class Strategy:
    channels: str = "fused"
    scope: str = "pooled"
    kind: str = "shift"
    normalise: str = "none"

    @property
    def name(self) -> str:
        return f"{self.channels}/{self.scope}/{self.kind}/{self.normalise}"


def corrected(strategy: Strategy, cal: list[dict[str, Any]], test: list[dict[str, Any]]):
    """Per channel: the calibration runs' scores corrected by bands without them, the test runs' by the band
    of all of them."""
    cal_ch = [channels_of(r["scores"], strategy.channels) for r in cal]
    test_ch = [channels_of(r["scores"], strategy.channels) for r in test]
    names = list(dict.fromkeys(c for run in cal_ch for c in run))
    cal_out: list[dict[str, np.ndarray]] = [{} for _ in cal]
    test_out: list[dict[str, np.ndarray]] = [{} for _ in test]
    for name in names:
        rows = [i for i, run in enumerate(cal_ch) if name in run and np.isfinite(run[name]).any()]
        series = [cal_ch[i][name] for i in rows]
        pooled_loo = leave_one_out(strategy.kind, series)
        pooled = fit_band(strategy.kind, series)
        for i, band in zip(rows, pooled_loo, strict=True):
            cal_out[i][name] = band.correct(cal_ch[i][name]).astype(np.float64)
        own = {}
        if strategy.scope == "task" or (strategy.scope == "task-signals" and name == "signals"):
            for task in sorted({cal[i]["task"] for i in rows}):
                mine = [i for i in rows if cal[i]["task"] == task]
                if len(mine) < MIN_TASK:
                    continue
                for i, band in zip(
                    mine, leave_one_out(strategy.kind, [cal_ch[i][name] for i in mine]), strict=True
                ):
                    cal_out[i][name] = band.correct(cal_ch[i][name]).astype(np.float64)
                own[task] = fit_band(strategy.kind, [cal_ch[i][name] for i in mine])
        for j, run in enumerate(test_ch):
            if name in run:
                band = own.get(test[j]["task"], pooled)
                test_out[j][name] = band.correct(run[name]).astype(np.float64)
    if strategy.normalise in ("gamma", "offset"):
        for name in names:
            rows = [i for i, run in enumerate(cal_out) if name in run]
            peaks = np.asarray([peak(cal_out[i][name]) for i in rows])
            scale_all = conformal_threshold([p for p in peaks if math.isfinite(p)], ALPHA)
            for k, i in enumerate(rows):
                others = [p for m, p in enumerate(peaks) if m != k and math.isfinite(p)]
                scale = conformal_threshold(others, ALPHA)
                cal_out[i][name] = normalised(cal_out[i][name], scale, strategy.normalise)
            for run in test_out:
                if name in run:
                    run[name] = normalised(run[name], scale_all, strategy.normalise)
    return [maxed(list(r.values())) for r in cal_out], [maxed(list(r.values())) for r in test_out]


def normalised(values: np.ndarray, threshold: float, how: str) -> np.ndarray:
    return values / max(threshold, 1e-6) if how == "gamma" else values - threshold


def auc(pos: np.ndarray, neg: np.ndarray) -> float:
    pos, neg = np.asarray(pos)[:, None], np.asarray(neg)[None, :]
    return float(((pos > neg).sum() + 0.5 * (pos == neg).sum()) / (pos.size * neg.size))


def evaluate(strategy: Strategy, cal: list[dict[str, Any]], test: list[dict[str, Any]]) -> dict[str, Any]:
    cal_fused, test_fused = corrected(strategy, cal, test)
    peaks = [peak(s) for s in cal_fused]
    gamma = conformal_threshold([p for p in peaks if math.isfinite(p)], ALPHA)
    failure = np.asarray([r["failure"] for r in test])
    fired, scores, ts = [], [], []
    for run, series in zip(test, test_fused, strict=True):
        hits = np.flatnonzero(np.nan_to_num(series, nan=-np.inf) >= gamma)
        fired.append(hits.size > 0)
        scores.append(np.nan_to_num(peak(series), nan=-np.inf))
        if run["failure"] and hits.size:
            ts.append(1 - hits[0] / len(series))
    fired_a, scores_a = np.asarray(fired), np.asarray(scores)
    return {
        "recall": 100 * fired_a[failure].mean(),
        "fpr": 100 * fired_a[~failure].mean(),
        "caught": int(fired_a[failure].sum()),
        "false": int(fired_a[~failure].sum()),
        "n": (int(failure.sum()), int((~failure).sum())),
        "ts": 100 * float(np.mean(ts)) if ts else float("nan"),
        "auc": auc(scores_a[failure], scores_a[~failure]),
        "gamma": gamma,
    }


STRATEGIES = [
    Strategy("cameras"),
    Strategy("signals"),
    Strategy("fused"),
    Strategy("fused", "task"),
    Strategy("fused", "pooled", "norm"),
    Strategy("fused", "task", "norm"),
    Strategy("view"),
    Strategy("view", "task"),
    Strategy("modality"),
    Strategy("modality", "task"),
    Strategy("modality", "pooled", "norm"),
    Strategy("modality", "pooled", "shift", "gamma"),
    Strategy("modality", "task", "shift", "gamma"),
    Strategy("modality", "pooled", "norm", "gamma"),
    Strategy("view", "pooled", "shift", "gamma"),
    Strategy("view", "task", "shift", "gamma"),
    Strategy("modality", "pooled", "shift", "offset"),
    Strategy("modality", "task", "shift", "offset"),
    Strategy("view", "pooled", "shift", "offset"),
    Strategy("view", "task", "shift", "offset"),
    Strategy("modality", "task", "norm"),
    Strategy("modality", "task-signals"),
    Strategy("cameras", "task"),
    Strategy("signals", "task"),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dump", type=Path)
    parser.add_argument("--only", nargs="*", default=None)
    args = parser.parse_args()
    print_machine()
    runs = load(args.dump)
    cells = []
    for half in ("id", "swapped"):
        cal = [r for r in runs if r["cell"] == f"{half}/cal"]
        if not cal:
            continue
        cells.append((f"{half}", cal, [r for r in runs if r["cell"] == f"{half}/test"]))
        if any(r["cell"] == f"{half}/ood" for r in runs):
            cells.append((f"{half} OOD", cal, [r for r in runs if r["cell"] == f"{half}/ood"]))
            cal2 = [r for r in runs if r["cell"] == f"{half}/cal+2"]
            cells.append((f"{half} OOD+2", cal2, [r for r in runs if r["cell"] == f"{half}/ood+2"]))
    print("strategy | " + " | ".join(label for label, _, _ in cells))
    for strategy in STRATEGIES:
        if args.only and strategy.name not in args.only:
            continue
        found = [evaluate(strategy, cal, test) for _, cal, test in cells]
        text = " | ".join(
            f"{c['recall']:.1f}/{c['fpr']:.1f} ({c['n'][0] - c['caught']}m,{c['false']}f) {c['ts']:.1f} ({c['auc']:.3f})"
            for c in found
        )
        print(f"{strategy.name} | {text}", flush=True)


if __name__ == "__main__":
    main()
