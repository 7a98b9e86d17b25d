"""Probe (issue 31): ways of fusing the views' contrast on the peer set, from probe_peer_views.py's dumps.

Run: .venv/bin/python -m bench.experiments.probe_peer_fusion [SLUG ...] [--window N]

Every fusion is calibrated as the library calibrates (split conformal at α on the memory half's
success runs, each with its own episode left out and each corrected by what the other runs fitted)
and judged on the other half, the OOD runs and the OOD runs with 2 deployment successes per task.
Candidates:
- `max`: the library's (shift band fitted on the max over views; max over views of the corrected);
- `max/view-band`: a shift band per view, then the max;
- `z`: a shift band per view, each view divided by the spread of its calibration peaks, then the max;
- `p`: each view's corrected score as its rank among that view's calibration peaks, then the max (min-p);
- `z·w`, `p·w`: `z`/`p` with each view weighted by its training separation (peak AUC of the memory
  half's failures against its successes, both with their own episode left out): w = (AUC−½)/(best−½), 0 at ≤ ½;
- `z-sel`, `p-sel`: `z`/`p` over the views whose training AUC ≥ SELECT only;
- `z·w-sum`: the w-weighted mean of the z-scores.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench._timing import print_machine
from bench.experiments.probe_peer_views import load
from robofailring.calibration.bands import fit_band, leave_one_out
from robofailring.calibration.conformal import auc, conformal_threshold
from robofailring.encoders import default_cache_dir

ALPHA = 0.05
SELECT = 0.6
Runs = list[dict[str, Any]]


def _peak(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else float("nan")


class ViewFit:
    """Per view: a shift band and the corrected peaks of the calibration runs it was fitted on."""

    def __init__(self, runs: Runs, views: Sequence[str]) -> None:
        self.views = list(views)
        self.band = {v: fit_band("shift", [r["scores"][v] for r in runs]) for v in views}
        self.peaks = {v: np.sort([_peak(self.band[v].correct(r["scores"][v])) for r in runs]) for v in views}

    def z(self, view: str, values: np.ndarray) -> np.ndarray:
        peaks = self.peaks[view]
        return (self.band[view].correct(values) - peaks.mean()) / max(peaks.std(), 1e-6)

    def p(self, view: str, values: np.ndarray) -> np.ndarray:
        """The corrected score's rank among the calibration peaks, interpolated, in [0, 1]."""
        peaks = self.peaks[view]
        corrected = self.band[view].correct(values)
        ranks = np.interp(corrected, peaks, np.linspace(0, 1, len(peaks) + 2)[1:-1], left=0.0, right=1.0)
        # beyond the highest peak keep ordering: 1 + distance in units of the peaks' spread
        above = corrected > peaks[-1]
        ranks = np.where(above, 1.0 + (corrected - peaks[-1]) / max(peaks.std(), 1e-6), ranks)
        return np.where(np.isfinite(corrected), ranks, np.nan)


def _loo_fits(runs: Runs, views: Sequence[str]) -> list[ViewFit]:
    return [ViewFit([r for j, r in enumerate(runs) if j != i], views) for i in range(len(runs))]


Fuse = Callable[[ViewFit, dict[str, np.ndarray], dict[str, float]], np.ndarray]


def _stack(parts: list[np.ndarray]) -> np.ndarray:
    return np.nan_to_num(np.stack(parts), nan=-np.inf)


def fusions() -> dict[str, Fuse]:
    def weighted(kind: str, mode: str) -> Fuse:
        def fuse(fit: ViewFit, scores: dict[str, np.ndarray], w: dict[str, float]) -> np.ndarray:
            norm = fit.z if kind == "z" else fit.p
            if mode == "w":
                chosen = [v for v in fit.views if w[v] > 0]
                return _stack([w[v] * norm(v, scores[v]) for v in chosen]).max(axis=0)
            if mode == "sel":
                chosen = [v for v in fit.views if w[v] >= SELECT] or [max(fit.views, key=lambda v: w[v])]
                return _stack([norm(v, scores[v]) for v in chosen]).max(axis=0)
            if mode == "sum":
                total = sum(w.values())
                return np.nansum([w[v] / total * norm(v, scores[v]) for v in fit.views], axis=0)
            return _stack([norm(v, scores[v]) for v in fit.views]).max(axis=0)

        return fuse

    def band_max(fit: ViewFit, scores: dict[str, np.ndarray], w: dict[str, float]) -> np.ndarray:
        return _stack([fit.band[v].correct(scores[v]) for v in fit.views]).max(axis=0)

    def band_sel(fit: ViewFit, scores: dict[str, np.ndarray], w: dict[str, float]) -> np.ndarray:
        chosen = [v for v in fit.views if w[v] >= SELECT] or [max(fit.views, key=lambda v: w[v])]
        return _stack([fit.band[v].correct(scores[v]) for v in chosen]).max(axis=0)

    return {
        "max/view-band": band_max,
        "view-band-sel": band_sel,
        "z": weighted("z", "max"),
        "p": weighted("p", "max"),
        "z·w": weighted("z", "w"),
        "p·w": weighted("p", "w"),
        "z-sel": weighted("z", "sel"),
        "p-sel": weighted("p", "sel"),
        "z·w-sum": weighted("z", "sum"),
    }


def training_weights(train: Runs, views: Sequence[str], kind: str = "auc") -> dict[str, float]:
    """Per view, its training separation: peak AUC of failures vs successes (own episode left out)."""
    separation = {}
    for v in views:
        fail = [_peak(r["scores"][v]) for r in train if r["failure"]]
        succ = [_peak(r["scores"][v]) for r in train if not r["failure"]]
        separation[v] = auc(fail, succ)
    best = max(separation.values())
    raw = {v: max(a - 0.5, 0.0) / max(best - 0.5, 1e-6) for v, a in separation.items()}
    if kind == "auc-raw":
        return separation
    return raw


def measure(fused: list[np.ndarray], runs: Runs, threshold: float) -> dict[str, float]:
    tp = fn = fp = tn = 0
    savings = []
    for values, run in zip(fused, runs, strict=True):
        hit = np.flatnonzero(values >= threshold)
        if run["failure"]:
            if hit.size:
                tp += 1
                savings.append(1 - hit[0] / len(values))
            else:
                fn += 1
        else:
            fp += bool(hit.size)
            tn += not hit.size
    fail = [_peak(f) for f, r in zip(fused, runs, strict=True) if r["failure"]]
    succ = [_peak(f) for f, r in zip(fused, runs, strict=True) if not r["failure"]]
    order = sorted(set(fail + succ))
    ceiling = max(
        (np.mean([f >= t for f in fail]) for t in order if np.mean([s >= t for s in succ]) <= 0.05),
        default=0.0,
    )
    return {
        "recall": 100 * tp / max(tp + fn, 1),
        "fpr": 100 * fp / max(fp + tn, 1),
        "ts": 100 * float(np.mean(savings)) if savings else float("nan"),
        "auc": auc(fail, succ),
        "ceiling": 100 * float(ceiling),
        "failures": tp + fn,
        "successes": fp + tn,
    }


def persist(values: np.ndarray, window: int) -> np.ndarray:
    """The running minimum over the last `window` frames: a score counts once it has held that long."""
    if window <= 1:
        return values
    padded = np.concatenate([np.full(window - 1, -np.inf), np.nan_to_num(values, nan=-np.inf)])
    return np.lib.stride_tricks.sliding_window_view(padded, window).min(axis=1)


WINDOW = 1


def evaluate(runs: Runs) -> dict[str, dict[str, dict[str, float]]]:
    views = sorted(runs[0]["scores"])
    train = [r for r in runs if r["cell"] == "train"]
    succ = [r for r in train if not r["failure"]]
    cells = {c: [r for r in runs if r["cell"] == c] for c in ("test", "ood", "ood+2")}
    weights = training_weights(train, views)
    results: dict[str, dict[str, dict[str, float]]] = {}
    # the library's: band fitted on the max over views
    raw = [_stack([r["scores"][v] for v in views]).max(axis=0) for r in succ]
    raw = [np.where(np.isfinite(x), x, np.nan) for x in raw]
    raw = [persist(x, WINDOW) for x in raw]
    raw = [np.where(np.isfinite(x), x, np.nan) for x in raw]
    loo = leave_one_out("shift", raw)
    threshold = conformal_threshold([_peak(b.correct(x)) for b, x in zip(loo, raw, strict=True)], ALPHA)
    band = fit_band("shift", raw)
    results["max"] = {
        c: measure(
            [
                band.correct(persist(_stack([r["scores"][v] for v in views]).max(axis=0), WINDOW))
                for r in cell
            ],
            cell,
            threshold,
        )
        for c, cell in cells.items()
    }
    fits = _loo_fits(succ, views)
    full = ViewFit(succ, views)
    for name, fuse in fusions().items():
        peaks = [
            _peak(persist(fuse(fit, r["scores"], weights), WINDOW)) for fit, r in zip(fits, succ, strict=True)
        ]
        threshold = conformal_threshold(peaks, ALPHA)
        results[name] = {
            c: measure([persist(fuse(full, r["scores"], weights), WINDOW) for r in cell], cell, threshold)
            for c, cell in cells.items()
        }
    tasks = sorted({r["task"] for r in succ})
    by_task = {t: [r for r in succ if r["task"] == t] for t in tasks}
    task_full = {t: ViewFit(by_task[t], views) for t in tasks}
    peaks = []
    for t in tasks:
        for fit, r in zip(_loo_fits(by_task[t], views), by_task[t], strict=True):
            peaks.append(
                _peak(
                    persist(_stack([fit.band[v].correct(r["scores"][v]) for v in views]).max(axis=0), WINDOW)
                )
            )
    threshold = conformal_threshold(peaks, ALPHA)
    results["task-view-band"] = {
        c: measure(
            [
                persist(
                    _stack([task_full[r["task"]].band[v].correct(r["scores"][v]) for v in views]).max(axis=0),
                    WINDOW,
                )
                for r in cell
            ],
            cell,
            threshold,
        )
        for c, cell in cells.items()
    }
    results["_weights"] = {v: {"w": w} for v, w in weights.items()}
    return results


def main() -> None:
    global WINDOW
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "slugs", nargs="*", help="dumps to read (default: every dump probe_peer_views.py wrote)"
    )
    parser.add_argument(
        "--window", type=int, default=WINDOW, help="frames a fused score must hold (persistence)"
    )
    args = parser.parse_args()
    print_machine()
    WINDOW = args.window
    folder = default_cache_dir() / "bench-peer" / "1b2338e2d3cc" / "probe-views"
    slugs = args.slugs or sorted(p.stem for p in folder.glob("*.npz"))
    print(
        "| dump | fusion | cell | recall (%) | FPR (%) | T_s (%) | AUC | best recall at FPR ≤ 5 % | failures/successes |"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|---|")
    for slug in slugs:
        results = evaluate(load(Path(folder / f"{slug}.npz")))
        weights = results.pop("_weights")
        named = ", ".join(f"{v} {w['w']:.2f}" for v, w in weights.items())
        print(f"| {slug} | training weights | {named} |")
        for name, cells in results.items():
            for cell, m in cells.items():
                print(
                    f"| {slug} | {name} | {cell} | {m['recall']:.1f} | {m['fpr']:.1f} | {m['ts']:.1f} | "
                    f"{m['auc']:.3f} | {m['ceiling']:.1f} | {m['failures']}/{m['successes']} |"
                )


if __name__ == "__main__":
    main()
