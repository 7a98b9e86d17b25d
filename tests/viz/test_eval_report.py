"""Evaluation at a glance: charts with their names on them, in the summary recording and in report.html."""

from __future__ import annotations

import copy
import json
import re
import subprocess
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from environment import chromium
from rrd import columns
from synthetic import write_project_dataset
from typer.testing import CliRunner

from rfr_viz.charts.evaluation import RULE_COLOURS, Mark, evaluation_charts, label_rows, marks_apart, rules_of
from rfr_viz.charts.report_html import write_report
from rfr_viz.cli.app import app
from rfr_viz.recordings.evaluation import chart_pages, record_evaluation

runner = CliRunner()


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    """`robofailring evaluate` run for real on a small project dataset: its folder and JSON."""
    tmp = tmp_path_factory.mktemp("evaluate")
    data = write_project_dataset(tmp / "data")
    out = tmp / "eval"
    result = runner.invoke(
        app,
        ["evaluate", str(data), "--out", str(out), "--target-fpr", "0.5", "--cache-dir", str(tmp / "cache")],
    )
    assert result.exit_code == 0, result.output
    assert f"report for a browser: {out / 'report.html'}" in result.output
    return out, json.loads((out / "evaluation.json").read_text())


def _two_rules(evaluation: dict[str, Any]) -> dict[str, Any]:
    """The evaluation with a second, made-up rule in the `rules` layout (γ thresholds)."""
    both = copy.deepcopy(evaluation)
    contrast = {
        "operating_gamma": 0.03,
        "sweep": [
            {"gamma": round(r["delta"] - 0.9, 4), "recall": r["recall"], "fpr": 0.0}
            for r in evaluation["sweep"]
        ],
        "recall_per_type": {
            kind: {**row, "recall": 0.5} for kind, row in evaluation["recall_per_type"].items()
        },
    }
    both["rules"] = {"paper": {}, "contrast": contrast}
    return both


def test_charts_carry_the_evaluation_values_and_names(evaluated: tuple[Path, dict[str, Any]]) -> None:
    _, evaluation = evaluated
    charts = {chart.key: chart for chart in evaluation_charts(evaluation)}
    assert list(charts) == [
        "roc",
        "sweep_paper",
        "sweep_contrast",
        "sweep_novelty",
        "recall_per_type",
        "recall_per_view",
        "progress_histogram",
    ]
    per_type = charts["recall_per_type"]
    assert per_type.categories == sorted(evaluation["recall_per_type"])
    assert per_type.series[0].values == [
        evaluation["recall_per_type"][k]["recall"] for k in per_type.categories
    ]
    contrast = evaluation["rules"]["contrast"]  # each rule is charted from its own scores
    assert per_type.series[1].values == [
        contrast["recall_per_type"][k]["recall"] for k in per_type.categories
    ]
    assert charts["sweep_contrast"].series[0].x == [row["delta"] for row in contrast["sweep"]]
    novelty = evaluation["rules"]["novelty"]  # the novelty rule, N_t against η, charted like the others
    assert (novelty["symbol"], novelty["score_name"]) == ("η", "N_t")
    assert per_type.series[2].values == [novelty["recall_per_type"][k]["recall"] for k in per_type.categories]
    assert [s.name for s in charts["roc"].series][2] == f"novelty (η = {novelty['threshold']:.3f})"
    assert charts["recall_per_view"].categories == [*evaluation["view_ablation"]]
    assert sum(charts["progress_histogram"].series[0].values) == sum(
        evaluation["progress_histogram"]["counts"]
    )
    sweep = charts["sweep_paper"]
    assert sweep.series[0].x == [row["delta"] for row in evaluation["sweep"]]
    assert sweep.marks[0].x == evaluation["operating_delta"]


def test_every_rule_is_charted(evaluated: tuple[Path, dict[str, Any]]) -> None:
    _, evaluation = evaluated
    rules = rules_of(_two_rules(evaluation))
    assert [(r.name, r.symbol, r.operating) for r in rules] == [
        ("paper", "δ", evaluation["operating_delta"]),
        ("contrast", "γ", 0.03),
    ]
    charts = {chart.key: chart for chart in evaluation_charts(_two_rules(evaluation))}
    assert {"sweep_paper", "sweep_contrast"} <= set(charts)
    assert [s.name for s in charts["roc"].series] == [
        f"paper (δ = {evaluation['operating_delta']:.3f})",
        "contrast (γ = 0.030)",
    ]
    assert charts["recall_per_type"].series[1].values == [0.5] * len(evaluation["recall_per_type"])


def _labels(path: Path, entity: str) -> list[str]:
    found: list[str] = []
    for row in columns(path, entity).get("Points2D:labels", []):
        found += row or []
    return found


def test_the_summary_recording_names_categories_on_the_charts(
    evaluated: tuple[Path, dict[str, Any]], tmp_path: Path
) -> None:
    out, evaluation = evaluated
    recorded = out / "evaluation.rrd"
    assert _labels(recorded, "/eval/evaluation/recall_per_type/categories") == sorted(
        evaluation["recall_per_type"]
    )
    values = _labels(recorded, "/eval/evaluation/recall_per_type/values")
    assert values == [  # per category, each rule's bar
        f"{100 * rule['recall_per_type'][k]['recall']:.0f}%"
        for k in sorted(evaluation["recall_per_type"])
        for rule in (evaluation, evaluation["rules"]["contrast"], evaluation["rules"]["novelty"])
    ]
    assert _labels(recorded, "/eval/evaluation/recall_per_view/categories") == [*evaluation["view_ablation"]]
    both = record_evaluation([_two_rules(evaluation)], out=tmp_path / "both.rrd")
    legend = _labels(both, "/eval/evaluation/roc/legend")
    assert len(legend) == 2 and legend[1] == "contrast (γ = 0.030)"


def test_report_html_is_self_contained_with_charts_tables_and_links(
    evaluated: tuple[Path, dict[str, Any]], tmp_path: Path
) -> None:
    out, evaluation = evaluated
    page = (out / "report.html").read_text(encoding="utf-8")
    assert page.count("<svg") == len(evaluation_charts(evaluation))
    assert not re.search(r'(src|href)="(https?:)?//', page), "the report loads something from elsewhere"
    for kind in evaluation["recall_per_type"]:
        assert f">{kind}</text>" in page and f"<td>{kind}</td>" in page
    links = re.findall(r'href="([^"]+)"', page)
    assert links == ["evaluation.rrd"] and (out / links[0]).is_file()
    assert (
        f"<code>{evaluation['encoder']}</code>, dense failure memory, change pairing</h2>" in page
    )  # which memory
    report = write_report([_two_rules(evaluation)], tmp_path / "report.html")
    assert "Recall and FPR against γ (contrast rule)" in report.read_text(encoding="utf-8")


@pytest.mark.slow  # a headless browser's start and render: the full lane, with the headless viewer's tests
def test_report_html_renders_in_headless_chromium(
    evaluated: tuple[Path, dict[str, Any]], tmp_path: Path
) -> None:
    browser = chromium()
    out, _ = evaluated
    shot = tmp_path / "report.png"
    subprocess.run(
        [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--screenshot={shot}",
         "--window-size=1280,900", (out / "report.html").resolve().as_uri()],
        capture_output=True, timeout=120, check=True,
    )  # fmt: skip
    image = cv2.imread(str(shot), cv2.IMREAD_COLOR)
    assert image is not None and image.shape[:2] == (900, 1280)
    drawn = sum(  # pixels of the rules' colours (BGR): bars and lines of the charts
        int(np.all(np.abs(image.astype(int) - colour[::-1]) < 12, axis=2).sum()) for colour in RULE_COLOURS
    )
    assert drawn > 2000, "no chart drawn in the browser"


def test_charts_stay_readable_at_1280_by_720(evaluated: tuple[Path, dict[str, Any]]) -> None:
    """Issue 32, item 6: at most four charts a tab, category names staggered by their length, and ROC
    points of one rule that land together share one label instead of drawing two over each other."""
    _, evaluation = evaluated
    charts = evaluation_charts(evaluation)
    pages = chart_pages(charts)
    assert list(pages) == ["ROC, when", "thresholds", "per type, view"]
    assert all(len(page) <= 4 for page in pages.values())
    assert sorted(c.key for page in pages.values() for c in page) == sorted(c.key for c in charts)
    assert label_rows(["front", "wrist"]) == 1 and label_rows(["0–20"] * 5) == 1
    assert (
        label_rows(
            ["grasp", "no_rotation", "rotation", "slip", "translation", "wrong_object", "wrong_sequence"]
        )
        == 3
    )
    blue, orange = RULE_COLOURS[0], RULE_COLOURS[1]
    marks = marks_apart(
        [
            Mark(0.0, 1.0, "δ=0.85", blue),
            Mark(0.01, 1.0, "δ=0.90", blue),  # the same ROC point: one label
            Mark(0.0, 1.0, "γ=0.10", orange),  # another rule's colour keeps its own
            Mark(0.5, 0.5, "δ=0.95", blue),
        ]
    )
    assert [(m.x, m.label) for m in marks] == [(0.0, "δ=0.85, 0.90"), (0.0, "γ=0.10"), (0.5, "δ=0.95")]


def _four_rules(evaluation: dict[str, Any]) -> dict[str, Any]:
    """The evaluation with a fourth rule in the `rules` layout: a rule added to the registry is charted."""
    more = copy.deepcopy(evaluation)
    more["rules"]["margin"] = {**copy.deepcopy(evaluation["rules"]["contrast"]), "symbol": "κ"}
    return more


def test_a_fourth_rule_is_charted_with_its_legend_inside_the_picture(
    evaluated: tuple[Path, dict[str, Any]],
) -> None:
    """A rule past the palette's three colours takes the first again (before: an IndexError in `evaluate`), and a
    legend too long for one row wraps to a second instead of running off the chart (before: cut off)."""
    from rfr_viz.charts.to_svg import WIDTH, chart_svg

    _, evaluation = evaluated
    three = next(chart for chart in evaluation_charts(evaluation) if chart.key == "roc")
    assert len(set(re.findall(r'<rect x="\d+" y="(\d+)" width="10"', chart_svg(three)))) == 1  # one row fits
    charts = {chart.key: chart for chart in evaluation_charts(_four_rules(evaluation))}
    assert "sweep_margin" in charts
    roc = charts["roc"]
    assert [s.name.split(" ")[0] for s in roc.series] == ["paper", "contrast", "novelty", "margin"]
    assert roc.series[3].colour == RULE_COLOURS[0]
    assert charts["sweep_margin"].marks[0].colour == RULE_COLOURS[0]
    svg = chart_svg(roc)
    legend = re.findall(r'<rect x="(\d+)" y="(\d+)" width="10" height="10"', svg)
    assert len(legend) == 4 and len({y for _, y in legend}) == 2  # two rows
    names = [s.name for s in roc.series]
    for (x, _), name in zip(legend, names, strict=True):  # each entry's text ends inside the picture
        assert int(x) + 14 + 6 * len(name) <= WIDTH, (x, name)
