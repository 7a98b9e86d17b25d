"""The evaluation summary recording: every chart with its names on it (rfr_viz.charts.evaluation), and the tables."""

from __future__ import annotations

import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any


from rfr_viz.charts.to_rerun import chart_view, log_chart
from rfr_viz.charts.evaluation import Chart, evaluation_charts
from rfr_viz.paths import EVAL_ROOT, EVAL_SUMMARY, EVALUATION_APPLICATION_ID
from robofailring.atomic import atomic_path
from robofailring.evaluation.run import EvaluationResult
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr
    import rerun.blueprint as rrb


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in name.lower())


def summary_blueprint(charts: Mapping[str, Sequence[Chart]]) -> rrb.Blueprint:
    """A tab per evaluation (ROC, sweeps, recall per type and per view, histogram), the tables beside."""
    tabs = [
        rrb.Grid(
            *(chart_view(f"{EVAL_ROOT}/{_slug(name)}/{chart.key}", chart) for chart in shown),
            grid_columns=3,
            name=name,
        )
        for name, shown in charts.items()
    ]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(*tabs), rrb.TextDocumentView(origin=EVAL_SUMMARY, name="tables"), column_shares=[3, 1]
        ),
        rrb.TimePanel(state="collapsed"),
        collapse_panels=True,
    )


def record_evaluation(
    results: Sequence[EvaluationResult | Mapping[str, Any]], *, out: Path, markdown: Sequence[str] = ()
) -> Path:
    """Write the summary `.rrd` of one or more evaluations (results, or their JSON with their
    `.md` tables as `markdown`), atomically."""
    out = Path(out)
    evaluations = [r.to_dict() if isinstance(r, EvaluationResult) else r for r in results]
    charts = {str(e["name"]): evaluation_charts(e) for e in evaluations}
    recording = rr.RecordingStream(EVALUATION_APPLICATION_ID, recording_id=str(uuid.uuid4()))
    with atomic_path(out, suffix=".rrd") as tmp:
        recording.save(str(tmp), default_blueprint=summary_blueprint(charts))
        for name, shown in charts.items():
            for chart in shown:
                log_chart(recording, f"{EVAL_ROOT}/{_slug(name)}/{chart.key}", chart)
        tables = [r.to_markdown() for r in results if isinstance(r, EvaluationResult)] + list(markdown)
        recording.log(
            EVAL_SUMMARY, rr.TextDocument("\n\n".join(tables), media_type=rr.MediaType.MARKDOWN), static=True
        )
        recording.flush()
        recording.disconnect()
    return out


__all__ = ["record_evaluation", "summary_blueprint"]
