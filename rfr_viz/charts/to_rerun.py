"""Evaluation charts (`eval_charts.Chart`) drawn as 2D primitives in Rerun, with their names on the chart.

Rerun's BarChart has no category labels, so each chart is drawn in a 2D view: the plot is the unit
square (y up), bars are boxes, curves are line strips, and every category, value, axis tick and
series name is a labelled point next to what it names.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

import numpy as np

from rfr_viz.charts.evaluation import LABEL_CHAR_WIDTH, Chart, Colour, label_rows
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr
    import rerun.blueprint as rrb

AXIS_COLOUR: Final[Colour] = (120, 120, 120)
TEXT_COLOUR: Final[Colour] = (210, 210, 210)
BOUNDS: Final[rrb.VisualBounds2D] = rrb.VisualBounds2D(x_range=[-0.16, 1.06], y_range=[-1.34, 0.24])
BAR_LINES: Final[int] = 24  # vertical lines that fill one bar


def chart_view(origin: str, chart: Chart) -> rrb.Spatial2DView:
    return rrb.Spatial2DView(origin=origin, name=chart.title, visual_bounds=BOUNDS)


def _value_text(chart: Chart, value: float) -> str:
    if math.isnan(value):
        return "n/a"
    return f"{100 * value:.0f}%" if chart.percent else f"{value:g}"


def _labels(
    rec: rr.RecordingStream,
    path: str,
    points: Sequence[tuple[float, float]],
    labels: Sequence[str],
    colours: Sequence[Colour],
) -> None:
    if points:
        rec.log(
            path,
            rr.Points2D(
                np.asarray(points, dtype=np.float32),
                labels=list(labels),
                colors=list(colours),
                radii=rr.Radius.ui_points(2.5),
                show_labels=True,
            ),
            static=True,
        )


def _frame(rec: rr.RecordingStream, origin: str, chart: Chart) -> None:
    """Axes, y grid with ticks, axis names and the series legend."""
    grid = [[[0.0, -y], [1.0, -y]] for y in (0.25, 0.5, 0.75, 1.0)]
    rec.log(
        f"{origin}/grid",
        rr.LineStrips2D(grid, colors=[(60, 60, 60)], radii=rr.Radius.ui_points(0.5)),
        static=True,
    )
    rec.log(
        f"{origin}/axes",
        rr.LineStrips2D(
            [[[0.0, -1.0], [0.0, 0.0], [1.0, 0.0]]], colors=[AXIS_COLOUR], radii=rr.Radius.ui_points(1.0)
        ),
        static=True,
    )
    ticks = (0.0, 0.5, 1.0)
    _labels(
        rec,
        f"{origin}/y_ticks",
        [(-0.09, -t) for t in ticks],
        [_value_text(chart, t * chart.y_max) for t in ticks],
        [AXIS_COLOUR] * len(ticks),
    )
    if chart.x_label:  # the y axis is named in the title
        below = 0.08 + 0.06 * label_rows(chart.categories) if chart.is_bars else 0.14  # under the names
        _labels(rec, f"{origin}/axis_name", [(0.5, min(below, 0.2))], [chart.x_label], [TEXT_COLOUR])
    _labels(
        rec,
        f"{origin}/legend",
        [
            (0.02 + 0.5 * (i % 2), -1.3 + 0.06 * (i // 2)) for i in range(len(chart.series))
        ],  # above the values
        [s.name for s in chart.series],
        [s.colour for s in chart.series],
    )


def _bars(rec: rr.RecordingStream, origin: str, chart: Chart) -> None:
    groups, per_group = len(chart.categories), max(len(chart.series), 1)
    width = 0.8 / max(groups, 1) / per_group
    crowded = width < 4 * LABEL_CHAR_WIDTH  # "100%" is wider than one bar
    strips, radii, colours, tops, texts = [], [], [], [], []
    for g in range(groups):
        for s, series in enumerate(chart.series):
            value = series.values[g] if g < len(series.values) else math.nan
            centre = (g + 0.1) / groups + (s + 0.5) * width
            height = 0.0 if math.isnan(value) else min(value / chart.y_max, 1.0)
            if height > 0:  # a solid bar: thin vertical lines side by side (Boxes2D draws outlines only)
                for x in centre + np.linspace(-0.42, 0.42, BAR_LINES) * width:
                    strips.append([[float(x), 0.0], [float(x), -height]])
                    radii.append(0.6 * width / BAR_LINES)
                    colours.append(series.colour)
            # a label sits just below its point; the series of crowded bars take their own levels
            tops.append((centre, -height - 0.09 - (0.05 * (s % 3) if crowded else 0.0)))
            texts.append(_value_text(chart, value))
    if strips:
        rec.log(f"{origin}/bars", rr.LineStrips2D(strips, radii=radii, colors=colours), static=True)
    _labels(
        rec,
        f"{origin}/values",
        tops,
        texts,
        [series.colour for _ in range(groups) for series in chart.series],
    )
    _labels(
        rec,
        f"{origin}/categories",
        [((g + 0.5) / groups, 0.06 + 0.06 * (g % label_rows(chart.categories))) for g in range(groups)],
        chart.categories,
        [TEXT_COLOUR] * groups,
    )


def _lines(rec: rr.RecordingStream, origin: str, chart: Chart) -> None:
    low, high = chart.x_range
    span = (high - low) or 1.0

    def place(x: float, y: float) -> tuple[float, float]:
        return (x - low) / span, -min(max(y / chart.y_max, 0.0), 1.0)

    for i, series in enumerate(chart.series):
        points = [place(x, y) for x, y in zip(series.x, series.values, strict=True) if not math.isnan(x + y)]
        if len(points) >= 2:
            rec.log(
                f"{origin}/series/{i}",
                rr.LineStrips2D([points], colors=[series.colour], radii=rr.Radius.ui_points(2.0)),
                static=True,
            )
    ticks = np.linspace(low, high, 5)
    _labels(
        rec,
        f"{origin}/x_ticks",
        [(place(float(t), 0.0)[0], 0.03) for t in ticks],
        [f"{t:.3g}" if (low, high) != (0.0, 1.0) else _value_text(chart, float(t)) for t in ticks],
        [AXIS_COLOUR] * len(ticks),
    )
    verticals = [[place(m.x, 0.0), place(m.x, chart.y_max)] for m in chart.marks if m.vertical]
    if verticals:
        rec.log(
            f"{origin}/thresholds",
            rr.LineStrips2D(
                verticals,
                colors=[m.colour for m in chart.marks if m.vertical],
                radii=rr.Radius.ui_points(1.0),
            ),
            static=True,
        )
    if chart.marks:
        _labels(
            rec,
            f"{origin}/marks",
            [place(m.x, m.y) for m in chart.marks],
            [m.label for m in chart.marks],
            [m.colour for m in chart.marks],
        )


def log_chart(rec: rr.RecordingStream, origin: str, chart: Chart) -> None:
    """Draw `chart` under `origin` (static): show it with `chart_view(origin, chart)`."""
    _frame(rec, origin, chart)
    (_bars if chart.is_bars else _lines)(rec, origin, chart)
