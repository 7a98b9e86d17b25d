"""The evaluation summary recording: every chart with its names on it (rfr_viz.charts.evaluation), and the tables."""

from __future__ import annotations

import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

from rfr_viz.charts.evaluation import Chart, evaluation_charts
from rfr_viz.charts.to_rerun import chart_view, log_chart
from rfr_viz.paths import EVAL_ROOT, EVAL_SUMMARY, EVALUATION_APPLICATION_ID
from robofailring.atomic import atomic_path
from robofailring.evaluation.result import EvaluationResult
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr
    import rerun.blueprint as rrb


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in name.lower())


#: The pages of one evaluation's charts, each few enough to read at 1280×720 (issue 32, item 6): a
#: chart's page by its key's first part.
PAGES: Final[dict[str, str]] = {
    "roc": "ROC, when",
    "progress_histogram": "ROC, when",
    "sweep": "thresholds",
    "growth": "growth",
}
OTHER_PAGE: Final[str] = "per type, view"


def chart_pages(shown: Sequence[Chart]) -> dict[str, list[Chart]]:
    """The charts by page, pages in the order their first chart comes."""
    pages: dict[str, list[Chart]] = {}
    for chart in shown:
        pages.setdefault(PAGES.get(chart.key.split("_")[0], PAGES.get(chart.key, OTHER_PAGE)), []).append(
            chart
        )
    return pages


def summary_blueprint(charts: Mapping[str, Sequence[Chart]]) -> rrb.Blueprint:
    """A tab per page of each evaluation's charts (ROC and when failures are detected; each rule's
    Recall/FPR sweep; recall per failure type and per view), at most four charts a tab so that each is
    large enough to read at 1280×720; the tables beside."""
    tabs = [
        rrb.Grid(
            *(chart_view(f"{EVAL_ROOT}/{_slug(name)}/{chart.key}", chart) for chart in page),
            grid_columns=2 if len(page) > 2 else len(page),
            name=f"{name} · {title}" if len(charts) > 1 else title,
        )
        for name, shown in charts.items()
        for title, page in chart_pages(shown).items()
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
    with atomic_path(out, suffix=".rrd", claim=True) as tmp:
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
