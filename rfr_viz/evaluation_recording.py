"""The evaluation summary recording: Recall/FPR against δ, ROC, detection-progress histogram, tables."""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from rfr_viz.paths import DELTA_TIMELINE, EVAL_ROOT, EVAL_SUMMARY, EVALUATION_APPLICATION_ID
from robofailring._atomic import atomic_path
from robofailring.evaluation import EvaluationResult
from robofailring.metrics import PAPER_DELTAS, rates, timeliness
from robofailring.scoring import ScoreRule


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in name.lower())


def summary_blueprint(names: Sequence[str]) -> rrb.Blueprint:
    """A tab per evaluation (curves, ROC, histogram, per-type recall) with the tables beside them."""
    tabs = []
    for name in names:
        base = f"{EVAL_ROOT}/{_slug(name)}"
        tabs.append(
            rrb.Grid(
                rrb.TimeSeriesView(origin=f"{base}/curve", name="Recall and FPR against δ×10⁴"),
                rrb.Spatial2DView(origin=f"{base}/roc", name="ROC: FPR (x) → Recall (up)"),
                rrb.BarChartView(
                    origin=f"{base}/progress_histogram", name="detection progress t_det/L (deciles)"
                ),
                rrb.BarChartView(origin=f"{base}/recall_per_type", name="recall per failure type"),
                grid_columns=2,
                name=name,
            )
        )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(*tabs), rrb.TextDocumentView(origin=EVAL_SUMMARY, name="tables"), column_shares=[3, 2]
        ),
        rrb.TimePanel(state="collapsed"),
        collapse_panels=True,
    )


def record_evaluation(results: Sequence[EvaluationResult], *, out: Path) -> Path:
    """Write the summary `.rrd` of one or more evaluations (e.g. in- and out-of-distribution), atomically."""
    out = Path(out)
    recording = rr.RecordingStream(EVALUATION_APPLICATION_ID, recording_id=str(uuid.uuid4()))
    with atomic_path(out, suffix=".rrd") as tmp:
        recording.save(str(tmp), default_blueprint=summary_blueprint([r.name for r in results]))
        for result in results:
            _log_result(recording, result)
        markdown = "\n\n".join(r.to_markdown() for r in results)
        recording.log(EVAL_SUMMARY, rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN), static=True)
        recording.flush()
        recording.disconnect()
    return out


def _log_result(recording: rr.RecordingStream, result: EvaluationResult) -> None:
    base = f"{EVAL_ROOT}/{_slug(result.name)}"
    recording.log(
        f"{base}/curve/recall", rr.SeriesLines(colors=[40, 160, 80], names="Recall", widths=2), static=True
    )
    recording.log(
        f"{base}/curve/fpr", rr.SeriesLines(colors=[220, 60, 50], names="FPR", widths=2), static=True
    )
    ticks = np.array([round(r.delta * 10_000) for r in result.curve], dtype=np.int64)
    recall = np.nan_to_num(np.array([r.recall for r in result.curve], dtype=np.float64), nan=0.0)
    fpr = np.nan_to_num(np.array([r.fpr for r in result.curve], dtype=np.float64), nan=0.0)
    time_column = rr.TimeColumn(DELTA_TIMELINE, sequence=ticks)
    recording.send_columns(
        f"{base}/curve/recall", indexes=[time_column], columns=rr.Scalars.columns(scalars=recall)
    )
    recording.send_columns(
        f"{base}/curve/fpr", indexes=[time_column], columns=rr.Scalars.columns(scalars=fpr)
    )
    operating = result.operating_delta
    # ROC in the unit square (y up): FPR on x, Recall on y.
    roc = np.stack([fpr, -recall], axis=1)
    recording.log(
        f"{base}/roc/curve", rr.LineStrips2D([roc], colors=[60, 120, 220], radii=0.004), static=True
    )
    paper = [r for r in result.paper_rates]
    recording.log(
        f"{base}/roc/paper_deltas",
        rr.Points2D(
            [[np.nan_to_num(r.fpr), -np.nan_to_num(r.recall)] for r in paper],
            labels=[f"δ={r.delta:.2f}" for r in paper],
            radii=0.015,
            colors=[230, 160, 30],
        ),
        static=True,
    )
    recording.log(
        f"{base}/roc/frame",
        rr.LineStrips2D([[[0, 0], [1, 0], [1, -1], [0, -1], [0, 0]]], colors=[90, 90, 90], radii=0.002),
        static=True,
    )
    _log_rule_rocs(recording, result, base)
    counts, _ = timeliness(result.scored, operating).histogram(bins=10)
    recording.log(
        f"{base}/progress_histogram",
        rr.BarChart(np.asarray(counts, dtype=np.float64), color=[60, 120, 220]),
        static=True,
    )
    per_type = result.per_type_recall(operating)
    recording.log(
        f"{base}/recall_per_type",
        rr.BarChart(
            np.nan_to_num(np.array([r.recall for r in per_type.values()], dtype=np.float64)),
            color=[40, 160, 80],
        ),
        static=True,
    )
    recording.log(
        f"{base}/recall_per_type/labels",
        rr.TextDocument(", ".join(f"{i}: {kind}" for i, kind in enumerate(per_type))),
        static=True,
    )


RULE_COLOURS = {"paper": (60, 120, 220), "contrast": (235, 90, 170)}


def _log_rule_rocs(recording: rr.RecordingStream, result: EvaluationResult, base: str) -> None:
    """Per scoring rule: its calibrated operating point and (beyond the paper's, drawn above) its ROC."""
    for name, row in result.rules.items():
        scored = result.rule_scored(row.rule)
        peaks = sorted({float(t.scores().max()) for t in scored if np.isfinite(t.scores().max())})
        curve = [rates(scored, threshold) for threshold in [*peaks, np.inf]]
        points = [[np.nan_to_num(r.fpr), -np.nan_to_num(r.recall)] for r in curve]
        colour = RULE_COLOURS.get(name, (200, 200, 200))
        if row.rule is not ScoreRule.PAPER:  # the paper rule's curve is roc/curve above
            recording.log(
                f"{base}/roc/{name}", rr.LineStrips2D([points], colors=[colour], radii=0.004), static=True
            )
        recording.log(
            f"{base}/roc/{name}/operating",
            rr.Points2D(
                [[np.nan_to_num(row.fpr), -np.nan_to_num(row.recall)]],
                labels=[f"{name} {row.rule.symbol}={row.threshold:.3f} (AUC {row.auc:.2f})"],
                radii=0.02,
                colors=[colour],
            ),
            static=True,
        )


__all__ = ["PAPER_DELTAS", "record_evaluation", "summary_blueprint"]
