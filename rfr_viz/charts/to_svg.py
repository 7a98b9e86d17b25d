"""Evaluation charts (`eval_charts.Chart`) as inline SVG for `report.html`: no plotting library needed."""

from __future__ import annotations

import math
from collections.abc import Callable
from html import escape
from typing import Final

from rfr_viz.charts.evaluation import Chart, Colour, label_rows

WIDTH: Final[int] = 460
HEIGHT: Final[int] = 300
LEFT, RIGHT, TOP, BOTTOM = 52, 16, 56, 52  # plot margins (px)
LEGEND_ROW: Final[int] = 13  # a legend row's height (px): two rows fit above the plot


def _rgb(colour: Colour) -> str:
    return f"rgb({colour[0]},{colour[1]},{colour[2]})"


def _text(
    x: float, y: float, text: str, *, anchor: str = "middle", size: int = 11, fill: str = "#333"
) -> str:
    return (
        f'<text x="{x:.1f}" y="{y:.1f}" text-anchor="{anchor}" font-size="{size}" fill="{fill}">'
        f"{escape(text)}</text>"
    )


def _value(chart: Chart, value: float) -> str:
    if math.isnan(value):
        return "n/a"
    return f"{100 * value:.0f}%" if chart.percent else f"{value:g}"


def chart_svg(chart: Chart) -> str:
    """The chart as one `<svg>` element with its title, axes, ticks, labels and legend."""
    plot_w, plot_h = WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM

    def y_of(value: float) -> float:
        return TOP + plot_h * (1 - min(max(value / chart.y_max, 0.0), 1.0))

    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" '
        f'viewBox="0 0 {WIDTH} {HEIGHT}" role="img" aria-label="{escape(chart.title)}">',
        '<rect width="100%" height="100%" fill="#fff"/>',
        _text(WIDTH / 2, 16, chart.title, size=13, fill="#111"),
    ]
    for tick in (0.0, 0.25, 0.5, 0.75, 1.0):
        y = y_of(tick * chart.y_max)
        parts.append(f'<line x1="{LEFT}" x2="{LEFT + plot_w}" y1="{y:.1f}" y2="{y:.1f}" stroke="#e4e4e4"/>')
        parts.append(_text(LEFT - 6, y + 4, _value(chart, tick * chart.y_max), anchor="end", size=10))
    parts.append(
        f'<polyline points="{LEFT},{TOP} {LEFT},{TOP + plot_h} {LEFT + plot_w},{TOP + plot_h}" '
        'fill="none" stroke="#777"/>'
    )
    parts += _bars(chart, plot_w, plot_h, y_of) if chart.is_bars else _lines(chart, plot_w, plot_h, y_of)
    if chart.x_label:
        parts.append(_text(LEFT + plot_w / 2, HEIGHT - 8, chart.x_label, size=11))
    x, y = LEFT, 25
    for series in chart.series:  # legend under the title, on a second row where the first is full
        width = 24 + 6 * len(series.name)  # its swatch, its text and the space before the next
        if x > LEFT and x + 14 + 6 * len(series.name) > WIDTH:  # its text would end past the picture
            x, y = LEFT, y + LEGEND_ROW
        parts.append(f'<rect x="{x}" y="{y}" width="10" height="10" fill="{_rgb(series.colour)}"/>')
        parts.append(_text(x + 14, y + 9, series.name, anchor="start", size=10))
        x += width
    parts.append("</svg>")
    return "\n".join(parts)


def _bars(chart: Chart, plot_w: int, plot_h: int, y_of: Callable[[float], float]) -> list[str]:
    groups, per_group = len(chart.categories), max(len(chart.series), 1)
    group_w = plot_w / max(groups, 1)
    bar_w = 0.8 * group_w / per_group
    parts = []
    rows = label_rows(
        chart.categories
    )  # many names: staggered a line lower each, so that they do not overlap
    for g, category in enumerate(chart.categories):
        below = 15 + 12 * (g % rows)
        parts.append(_text(LEFT + (g + 0.5) * group_w, TOP + plot_h + below, category, size=10))
        for s, series in enumerate(chart.series):
            value = series.values[g] if g < len(series.values) else math.nan
            x = LEFT + (g + 0.1) * group_w + s * bar_w
            top = y_of(0.0 if math.isnan(value) else value)
            parts.append(
                f'<rect x="{x:.1f}" y="{top:.1f}" width="{bar_w * 0.92:.1f}" height="{TOP + plot_h - top:.1f}" '
                f'fill="{_rgb(series.colour)}"><title>{escape(series.name)}: {_value(chart, value)}</title></rect>'
            )
            parts.append(
                _text(x + bar_w * 0.46, top - 3, _value(chart, value), size=9, fill=_rgb(series.colour))
            )
    return parts


def _lines(chart: Chart, plot_w: int, plot_h: int, y_of: Callable[[float], float]) -> list[str]:
    low, high = chart.x_range
    span = (high - low) or 1.0

    def x_of(value: float) -> float:
        return LEFT + plot_w * (value - low) / span

    parts = []
    for t in range(5):
        value = low + span * t / 4
        label = _value(chart, value) if (low, high) == (0.0, 1.0) else f"{value:.3g}"
        parts.append(_text(x_of(value), TOP + plot_h + 15, label, size=10))
    for series in chart.series:
        points = " ".join(
            f"{x_of(x):.1f},{y_of(y):.1f}"
            for x, y in zip(series.x, series.values, strict=True)
            if not math.isnan(x + y)
        )
        parts.append(
            f'<polyline points="{points}" fill="none" stroke="{_rgb(series.colour)}" stroke-width="2"/>'
        )
    for mark in chart.marks:
        x, y = x_of(mark.x), y_of(mark.y)
        if mark.vertical:
            parts.append(
                f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{TOP}" y2="{TOP + plot_h}" stroke="{_rgb(mark.colour)}" '
                'stroke-dasharray="4 3"/>'
            )
        parts.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="3.5" fill="{_rgb(mark.colour)}"/>')
        right = x > LEFT + 0.6 * plot_w  # labels near the right edge extend to the left
        parts.append(
            _text(
                x + (-5 if right else 5),
                y + 12,
                mark.label,
                anchor="end" if right else "start",
                size=9,
                fill=_rgb(mark.colour),
            )
        )
    return parts
