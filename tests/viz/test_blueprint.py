"""Recording layouts: one set of score plots per encoder, thresholds named in the titles, no legend over a plot."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import rerun.blueprint as rrb

from rfr_viz.panels.map import MapGrid
from rfr_viz.panels.neighbors import DEFAULT_CELL
from rfr_viz.paths import REPLAY, DetectorPaths
from rfr_viz.recordings.blueprint import ScorePlots, compare_blueprint, replay_blueprint
from robofailring.detection.rules import CONTRAST, NOVELTY

VIEWS = ["front", "overhead", "wrist"]
GRID = MapGrid(views=3, legend_entries=7)


def _views(part: Any) -> Iterator[Any]:
    """Every view inside a blueprint part, depth first."""
    if isinstance(part, rrb.Blueprint):
        yield from _views(part.root_container)
    elif isinstance(part, rrb.Container):
        for child in part.contents:
            yield from _views(child)
    else:
        yield part


def _time_series(blueprint: rrb.Blueprint) -> list[rrb.TimeSeriesView]:
    return [view for view in _views(blueprint) if isinstance(view, rrb.TimeSeriesView)]


def _legend_visible(view: rrb.TimeSeriesView) -> bool:
    legend = view.properties["PlotLegend"]
    return bool(legend.visible is None or legend.visible.as_arrow_array()[0].as_py())


def _contents(view: rrb.TimeSeriesView) -> list[str]:
    return [str(item) for item in view.contents]


def test_a_replay_names_its_thresholds_and_keeps_every_plot_free_of_legends() -> None:
    plots = ScorePlots.of(
        judging=CONTRAST,
        thresholds={"paper": 0.984, "contrast": 0.082, "novelty": 0.1},
        failures=True,
        successes=True,
    )
    blueprint = replay_blueprint(
        views=VIEWS, map_title="map", map_grid=GRID, cell=DEFAULT_CELL, k=3, plots=plots
    )
    scores, contrast, state = _time_series(blueprint)
    assert str(scores.name).startswith("δ = 0.984 · S_t (bold), S⁺_t (faint)")
    assert str(contrast.name).startswith("γ = 0.082 · C_t")
    assert not any(_legend_visible(view) for view in (scores, contrast, state))
    # the contrast rule's plot: S⁻, S⁺ and δ, not the novelty rule's N and η
    assert REPLAY.threshold("paper") in _contents(scores) and REPLAY.success_score("wrist") in _contents(
        scores
    )
    assert REPLAY.threshold("novelty") not in _contents(scores) and REPLAY.score(
        "front", "novelty"
    ) not in _contents(scores)
    assert _contents(contrast) == [REPLAY.score(view, "contrast") for view in VIEWS] + [
        REPLAY.threshold("contrast")
    ]


def test_a_task_without_failures_shows_novelty_and_eta() -> None:
    plots = ScorePlots.of(
        judging=NOVELTY,
        thresholds={"paper": 0.9, "contrast": 0.1, "novelty": 0.25},
        failures=False,
        successes=True,
    )
    assert plots.rules == (NOVELTY,) and plots.thresholds == {"novelty": 0.25}
    blueprint = replay_blueprint(
        views=VIEWS, map_title="map", map_grid=GRID, cell=DEFAULT_CELL, k=3, plots=plots
    )
    scores, _ = _time_series(blueprint)
    assert "η = 0.250" in str(scores.name) and REPLAY.threshold("novelty") in _contents(scores)
    assert REPLAY.threshold("paper") not in _contents(scores)


def test_a_comparison_has_score_plots_of_its_own_per_encoder() -> None:
    plots = [
        ScorePlots.of(
            judging=CONTRAST,
            thresholds={"paper": 0.984, "contrast": 0.082, "novelty": 0.1},
            failures=True,
            successes=True,
        ),
        ScorePlots.of(
            judging=CONTRAST,
            thresholds={"paper": 0.990, "contrast": 0.022, "novelty": 0.1},
            failures=True,
            successes=True,
        ),
    ]
    blueprint = compare_blueprint(
        views=VIEWS,
        encoders=["pixels", "trained"],
        map_titles=["map", "map"],
        map_grids=[GRID, GRID],
        cells=[DEFAULT_CELL, DEFAULT_CELL],
        plots=plots,
    )
    series = _time_series(blueprint)
    assert len(series) == 6  # S, C and State for each encoder
    for slug, delta, gamma in (("pixels", "0.984", "0.082"), ("trained", "0.990", "0.022")):
        own = [view for view in series if str(view.name).startswith(f"{slug} · ")]
        assert len(own) == 3
        assert str(own[0].name).startswith(f"{slug} · δ = {delta}") and f"γ = {gamma}" in str(own[1].name)
        prefix = DetectorPaths.for_encoder(slug).prefix
        assert all(path.startswith(prefix) for view in own for path in _contents(view))
        assert not any(_legend_visible(view) for view in own)
