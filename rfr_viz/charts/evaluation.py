"""The evaluation's charts, drawn once as data and rendered to Rerun (`chart_rerun`) and to SVG (`chart_svg`).

Charts are built from the evaluation JSON (`EvaluationResult.to_dict()`), one series per scoring
rule: today's evaluation has the paper's rule (S_t ≥ δ); an evaluation whose JSON has a `rules`
mapping (e.g. `rules.paper`, `rules.contrast`, `rules.novelty`) shows every rule side by side. A rule's dict holds
the same keys as the top level (`sweep`, `paper_deltas`, `recall_per_type`, `view_ablation`,
`progress_histogram`, `operating_delta`); rows and operating points may name their threshold
`delta`, `gamma` or `threshold`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Final

Colour = tuple[int, int, int]
RULE_COLOURS: Final[tuple[Colour, ...]] = ((60, 120, 220), (235, 130, 40), (150, 90, 200))
RECALL_COLOUR: Final[Colour] = (40, 160, 80)
FPR_COLOUR: Final[Colour] = (220, 60, 50)


def rule_colour(i: int) -> Colour:
    """The `i`-th rule's colour, the palette repeated for a fourth rule and on."""
    return RULE_COLOURS[i % len(RULE_COLOURS)]


_THRESHOLD_KEYS: Final[tuple[str, ...]] = ("threshold", "delta", "gamma")


@dataclass(frozen=True)
class Series:
    name: str
    colour: Colour
    values: list[float]  # bars: one per category; lines: y per x
    x: list[float] = field(default_factory=list)  # lines only


@dataclass(frozen=True)
class Mark:
    """A labelled point on a line chart (an operating threshold, a paper δ)."""

    x: float
    y: float
    label: str
    colour: Colour
    vertical: bool = False  # also a line across the plot at x (a threshold)


@dataclass(frozen=True)
class Chart:
    """A bar chart (`categories` set) or a line chart (series with x), values in [0, 1] unless `y_max`."""

    key: str  # entity-safe name
    title: str
    series: list[Series]
    categories: list[str] = field(default_factory=list)
    x_label: str = ""
    y_label: str = ""
    x_range: tuple[float, float] = (0.0, 1.0)
    y_max: float = 1.0
    percent: bool = True  # values are rates, shown as %
    marks: list[Mark] = field(default_factory=list)

    @property
    def is_bars(self) -> bool:
        return bool(self.categories)


@dataclass(frozen=True)
class Rule:
    """One scoring rule's results, read from the evaluation JSON."""

    name: str  # "paper", "contrast", …
    symbol: str  # "δ" or "γ"
    operating: float
    sweep: list[tuple[float, float, float]]  # (threshold, recall, fpr)
    marked: list[tuple[float, float, float]]  # the paper's δ values (or a rule's own), same layout
    per_type: dict[str, float]
    per_view: dict[str, tuple[float, float]]  # view (and "fusion") -> (recall, fpr)
    histogram: tuple[list[int], list[float]]  # detection progress counts and bin edges


def _rate(value: Any) -> float:
    return float("nan") if value is None else float(value)


def _threshold(row: Mapping[str, Any]) -> float:
    return float(next(row[key] for key in _THRESHOLD_KEYS if key in row))


def _rows(rows: Sequence[Mapping[str, Any]]) -> list[tuple[float, float, float]]:
    return [(_threshold(r), _rate(r.get("recall")), _rate(r.get("fpr"))) for r in rows]


def _rule(name: str, data: Mapping[str, Any], top: Mapping[str, Any]) -> Rule:
    def get(key: str, default: Any = None) -> Any:
        return data.get(key, top.get(key, default))

    symbol = (
        data.get("symbol")
        or (  # evaluations written before rules named their symbol
            "γ" if name == "contrast" or any("gamma" in r for r in get("sweep", [])[:1]) else "δ"
        )
    )
    keys = ("operating_threshold", "operating_delta", "operating_gamma")  # the rule's own first
    found = [source[key] for source in (data, top) for key in keys if source.get(key) is not None]
    operating = float(found[0]) if found else math.nan
    histogram = get("progress_histogram", {})
    return Rule(
        name=name,
        symbol=symbol,
        operating=operating,
        sweep=_rows(get("sweep", [])),
        marked=_rows(get("paper_deltas", [])) if symbol == "δ" else _rows(data.get("marked", [])),
        per_type={kind: _rate(row.get("recall")) for kind, row in get("recall_per_type", {}).items()},
        per_view={
            v: (_rate(r.get("recall")), _rate(r.get("fpr"))) for v, r in get("view_ablation", {}).items()
        },
        histogram=(list(histogram.get("counts", [])), list(histogram.get("edges", []))),
    )


def rules_of(evaluation: Mapping[str, Any]) -> list[Rule]:
    """Every scoring rule of an evaluation JSON: its `rules` mapping, else the paper's rule alone."""
    named = evaluation.get("rules")
    if isinstance(named, Mapping) and named:
        return [_rule(str(name), data, evaluation) for name, data in named.items()]
    return [_rule("paper", evaluation, evaluation)]


def _label(rule: Rule) -> str:
    return f"{rule.name} ({rule.symbol} = {rule.operating:.3f})"


def _bars(key: str, title: str, rules: Sequence[Rule], table: list[dict[str, float]]) -> Chart:
    categories = list(dict.fromkeys(category for values in table for category in values))
    return Chart(
        key=key,
        title=title,
        categories=categories,
        series=[
            Series(
                _label(rule),
                rule_colour(i),
                [values.get(c, math.nan) for c in categories],
            )
            for i, (rule, values) in enumerate(zip(rules, table, strict=True))
        ],
    )


def _fifths(counts: Sequence[int]) -> list[int]:
    """Detection-progress counts over equal bins, summed into fifths of the trajectory (5 readable bars)."""
    if not counts:
        return []
    bins = len(counts)
    return [sum(c for b, c in enumerate(counts) if min(5 * b // bins, 4) == fifth) for fifth in range(5)]


MARK_SPACING: Final[float] = 0.06  # of the plot's unit square: closer marks of one colour share one label


LABEL_CHAR_WIDTH: Final[float] = 0.028  # one character of a name, of a chart's width at 1280×720 (measured)


def label_rows(categories: Sequence[str]) -> int:
    """Rows a bar chart's category names are staggered over (both renderers), 1 to 3: enough that
    names in one row, that many groups apart, do not overlap at 1280×720."""
    longest = max((len(name) for name in categories), default=0)
    return min(3, max(1, math.ceil(longest * LABEL_CHAR_WIDTH * len(categories))))


def marks_apart(marks: list[Mark]) -> list[Mark]:
    """The marks with those of one colour that land within MARK_SPACING of an earlier one joined into
    it (`δ=0.92, 0.95`), so no two labels are drawn over each other (two thresholds with one ROC point)."""
    kept: list[Mark] = []
    for mark in marks:
        near = next(
            (
                i
                for i, other in enumerate(kept)
                if other.colour == mark.colour
                and math.hypot(other.x - mark.x, other.y - mark.y) < MARK_SPACING
            ),
            None,
        )
        if near is None:
            kept.append(mark)
        else:
            other = kept[near]
            kept[near] = replace(other, label=f"{other.label}, {mark.label.split('=', 1)[-1]}")
    return kept


def evaluation_charts(evaluation: Mapping[str, Any]) -> list[Chart]:
    """ROC, Recall/FPR sweeps, recall per failure type and per view, detection-progress histogram."""
    rules = rules_of(evaluation)
    charts = [
        Chart(
            key="roc",
            title="ROC: FPR → Recall"
            + ({1: "", 2: " (both rules)"}.get(len(rules), f" ({len(rules)} rules)")),
            x_label="false-positive rate",
            y_label="recall",
            series=[
                Series(
                    _label(r),
                    rule_colour(i),
                    [s[1] for s in r.sweep],
                    [s[2] for s in r.sweep],
                )
                for i, r in enumerate(rules)
            ],
            marks=marks_apart(
                [
                    Mark(fpr, recall, f"{r.symbol}={t:.2f}", rule_colour(i))
                    for i, r in enumerate(rules)
                    for t, recall, fpr in r.marked
                    if not (math.isnan(recall) or math.isnan(fpr))
                ]
            ),
        )
    ]
    for i, rule in enumerate(rules):
        thresholds = [s[0] for s in rule.sweep] or [0.0, 1.0]
        charts.append(
            Chart(
                key=f"sweep_{rule.name}",
                title=f"Recall and FPR against {rule.symbol} ({rule.name} rule)",
                x_label=rule.symbol,
                y_label="rate",
                x_range=(min(thresholds), max(thresholds)),
                series=[
                    Series("Recall", RECALL_COLOUR, [s[1] for s in rule.sweep], [s[0] for s in rule.sweep]),
                    Series("FPR", FPR_COLOUR, [s[2] for s in rule.sweep], [s[0] for s in rule.sweep]),
                ],
                marks=[
                    Mark(
                        rule.operating,
                        1.0,
                        f"operating {rule.symbol} = {rule.operating:.3f}",
                        rule_colour(i),
                        vertical=True,
                    )
                ]
                if not math.isnan(rule.operating)
                else [],
            )
        )
    charts.append(
        _bars("recall_per_type", "Recall per failure type", rules, [dict(r.per_type) for r in rules])
    )
    charts.append(
        _bars(
            "recall_per_view",
            "Recall per view (fusion = any view)",
            rules,
            [{view: rates[0] for view, rates in r.per_view.items()} for r in rules],
        )
    )
    counts = [_fifths(r.histogram[0]) for r in rules]
    peak = max((max(c) for c in counts if c), default=0)
    charts.append(
        Chart(
            key="progress_histogram",
            title="When failures are detected: t_det / L",
            categories=[f"{20 * b}–{20 * (b + 1)}" for b in range(5)] if any(counts) else [],
            series=[
                Series(_label(r), rule_colour(i), [float(c) for c in shown])
                for i, (r, shown) in enumerate(zip(rules, counts, strict=True))
            ],
            y_max=float(max(peak, 1)),
            percent=False,
            x_label="detected failures by t_det / L (%)",
        )
    )
    growth = evaluation.get("growth") or []
    if growth:
        charts.append(growth_chart(growth))
    return charts


def growth_chart(points: Sequence[Mapping[str, Any]]) -> Chart:
    """The learning curve (`evaluate --growth`): recall and FPR per level of labelled failures per task."""
    return Chart(
        key="growth",
        title="Learning curve: labelled failures per task → Recall and FPR (default rule)",
        categories=[
            f"{'all' if p['failures_per_task'] is None else p['failures_per_task']} · {p['rule']}"
            for p in points
        ],
        series=[
            Series("Recall", RECALL_COLOUR, [_rate(p.get("recall")) for p in points]),
            Series("FPR", FPR_COLOUR, [_rate(p.get("fpr")) for p in points]),
        ],
        x_label="labelled failures per task · rule",
    )
