"""The layouts saved inside recordings: pure functions of the views, the encoders and the image size."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from rfr_viz.panels.map import MapGrid
from rfr_viz.panels.neighbors import Cell
from rfr_viz.panels.scores import threshold_label
from rfr_viz.paths import (
    CLOSED_LOOP_SUMMARY,
    DEFAULT_FPS,
    FRAME,
    REPLAY,
    UNSTOPPED,
    WATCHED,
    DetectorPaths,
    camera,
    signal,
)
from robofailring.detection.band import Band
from robofailring.detection.rules import ScoringRule, shown_rules
from robofailring.extras import needs_extra
from robofailring.memory.signals.modality import SIGNALS_VIEW

with needs_extra("viz"):
    import rerun.blueprint as rrb

MAP_BACKGROUND = (22, 22, 26)


def map_bounds(grid: MapGrid) -> rrb.VisualBounds2D:
    """The map panel's viewport: every view's map and the legend."""
    x_range, y_range = grid.bounds()
    return rrb.VisualBounds2D(x_range=x_range, y_range=y_range)


def _cameras(views: Sequence[str]) -> rrb.Container:
    return rrb.Horizontal(*(rrb.Spatial2DView(origin=camera(view), name=view) for view in views))


@dataclass(frozen=True)
class ScorePlots:
    """What one detector's score plots show: one plot per rule shown, its scores per view against its
    threshold, titled with the threshold's value (and its band's line, if any)."""

    rules: tuple[ScoringRule, ...] = ()  # the rules shown (`robofailring.detection.rules.shown_rules`)
    thresholds: Mapping[str, float] = field(default_factory=dict)  # per rule name: its threshold θ
    successes: bool = False  # S⁺_t per view, faint, in the first plot
    bands: Mapping[str, Band] = field(default_factory=dict)  # per rule name: its time-indexed band, if any
    signals: bool = False  # the robot's signals scored too: their lines (view `signals`) beside the cameras'

    @classmethod
    def of(
        cls,
        *,
        judging: ScoringRule,
        thresholds: Mapping[str, float],
        failures: bool,
        successes: bool,
        bands: Mapping[str, Band] | None = None,
        signals: bool = False,
    ) -> ScorePlots:
        """The plots of the rules shown beside the `judging` one (`shown_rules`: a rule needing S⁻ only
        where the task has failure entries, one needing S⁺ only with success runs), each at its threshold
        in `thresholds` (by rule name), named as the line its band makes of it."""
        rules = tuple(shown_rules(judging, successes=successes, failures=failures))
        return cls(
            rules=rules,
            thresholds={
                rule.name: float(thresholds.get(rule.name, rule.default_threshold)) for rule in rules
            },
            successes=successes,
            bands=dict(bands or {}),
            signals=signals,
        )

    def scored(self, views: Sequence[str]) -> list[str]:
        """The views whose scores are plotted: the cameras, and the signals where they were scored."""
        return [*views, SIGNALS_VIEW] if self.signals else list(views)


# Score plots have no legend: at 1280×720 one covered a third of the plot and still cut lines off. Their
# titles name each threshold with its value, first (what a narrow title keeps); a view's colour is its
# query marker's in the memory map, under the view's name; every line's name shows on hover.
NO_LEGEND = rrb.PlotLegend(visible=False)


def _score_plot(
    paths: DetectorPaths, *, views: Sequence[str], plots: ScorePlots, label: str = ""
) -> rrb.Container:
    """One plot per rule shown: its score of every view with its threshold (the first also S⁺_t, faint);
    State_t (0/1) in a thin plot below, so each keeps its scale."""
    rule_plots = []
    views = plots.scored(views)
    for position, rule in enumerate(plots.rules):
        own = (
            plots.bands[rule.name].views if rule.name in plots.bands else {}
        )  # views with a band of their own
        contents = [
            *(paths.score(view, rule.name) for view in views),
            paths.threshold(rule.name),
            *(paths.view_threshold(rule.name, view) for view in views if view in own),
        ]
        faint = ""
        if position == 0 and plots.successes:
            contents += [paths.success_score(view) for view in views]
            faint = " (bold), S⁺_t (faint)"
        threshold = threshold_label(rule, plots.thresholds[rule.name], plots.bands.get(rule.name))
        rule_plots.append(
            rrb.TimeSeriesView(
                origin="/",
                contents=contents,
                name=f"{label}{threshold} · {rule.formula}{faint} per view",
                plot_legend=NO_LEGEND,
            )
        )
    state = rrb.TimeSeriesView(
        origin="/",
        contents=[paths.state],
        name=f"{label}State_t (fused over views)",
        plot_legend=NO_LEGEND,
        axis_y=rrb.ScalarAxis(range=(-0.1, 1.1), zoom_lock=True),
    )
    shares = [2.4 if len(rule_plots) > 1 else 3.0] * len(rule_plots)
    return rrb.Vertical(*rule_plots, state, row_shares=[*shares, 1.0 if len(rule_plots) > 1 else 1.2])


def _map(paths: DetectorPaths, *, name: str, grid: MapGrid) -> rrb.Spatial2DView:
    return rrb.Spatial2DView(
        origin=paths.map_root, name=name, background=MAP_BACKGROUND, visual_bounds=map_bounds(grid)
    )


def _neighbor_grids(
    views: Sequence[str], k: int, paths: DetectorPaths, cell: Cell, *, label: str = ""
) -> list[rrb.View]:
    """Per view: the grid of all K neighbours (row = rank: start | end), opened on rank 1."""
    x_range, y_range = cell.top_row
    more = f" (zoom out: #2–#{k})" if k > 1 else ""
    return [
        rrb.Spatial2DView(
            origin=f"{paths.neighbors_root}/{view}",
            name=f"{label}{view} · nearest: start | end{more}",
            visual_bounds=rrb.VisualBounds2D(x_range=x_range, y_range=y_range),
        )
        for view in views
    ]


def _nearest_successes(views: Sequence[str], paths: DetectorPaths) -> list[rrb.Container]:
    """Per view: the nearest success frame ("what normal looked like here") beside its text."""
    return [
        rrb.Horizontal(
            rrb.Spatial2DView(origin=paths.nearest_success(view), name=f"{view} · normal here"),
            rrb.TextDocumentView(
                origin=paths.nearest_success_info(view), name=f"{view} · nearest success run"
            ),
            column_shares=[1, 1.3],
        )
        for view in views
    ]


def _neighbor_infos(views: Sequence[str], paths: DetectorPaths, *, label: str = "") -> list[rrb.View]:
    return [
        rrb.TextDocumentView(origin=paths.neighbor(view, 0, "info"), name=f"{label}{view} · nearest #1")
        for view in views
    ]


FOCUS_MARGIN = 6  # frames shown either side of a focus frame (an alarm, a near miss)


def signal_plots(signals: Sequence[str]) -> list[rrb.View]:
    """One time-series plot per signal of the robot (`/signals/<name>`), a named line per dimension."""
    return [rrb.TimeSeriesView(origin=signal(name), name=name) for name in signals]


def side_panels(fps: float, focus: int | None = None) -> list[rrb.BlueprintPart]:
    """Side panels folded away; the time bar plays the "frame" timeline at the data's rate.

    With a `focus` frame the time bar selects the frames around it and playback loops there once it
    reaches them (Rerun 0.41 blueprints cannot place the time cursor itself).
    """
    if focus is None:
        time_panel = rrb.TimePanel(state="collapsed", timeline=FRAME, fps=fps)
    else:
        selection = rrb.components.AbsoluteTimeRange(max(focus - FOCUS_MARGIN, 0), focus + FOCUS_MARGIN)
        time_panel = rrb.TimePanel(
            state="collapsed",
            timeline=FRAME,
            fps=fps,
            time_selection=selection,
            loop_mode="selection",
            play_state="playing",
        )
    return [rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"), time_panel]


def replay_blueprint(
    *,
    views: Sequence[str],
    map_title: str,
    map_grid: MapGrid,
    cell: Cell,
    k: int,
    plots: ScorePlots,
    fps: float = DEFAULT_FPS,
    focus: int | None = None,
    signals: Sequence[str] = (),
) -> rrb.Blueprint:
    """Cameras, score plots and memory map on top; neighbours (and nearest successes), the report and the
    robot's `signals` (a tab each) below."""
    top = rrb.Horizontal(
        _cameras(views),
        _score_plot(REPLAY, views=views, plots=plots),
        _map(REPLAY, name=map_title, grid=map_grid),
        column_shares=[0.85 * len(views), 2.2, 2.0],
    )
    neighbors = rrb.Grid(
        *_neighbor_grids(views, k, REPLAY, cell),
        *(_nearest_successes(views, REPLAY) if plots.successes else []),
        *_neighbor_infos(views, REPLAY),
        grid_columns=len(views),
        row_shares=[1, 0.8, 0.8] if plots.successes else [1, 1],
        name="nearest memory entries",
    )
    side = rrb.Tabs(
        rrb.TextDocumentView(origin=REPLAY.report, name="failure report"),
        rrb.TextLogView(
            origin="/", contents=[f"{REPLAY.detection_root}/**", f"{REPLAY.neighbors_root}/**"], name="events"
        ),
        active_tab=0,
    )
    robot = [rrb.Tabs(*signal_plots(signals), name="robot signals")] if signals else []
    bottom = rrb.Horizontal(neighbors, side, *robot, column_shares=[3, 1.6, 1.8][: 2 + len(robot)])
    return rrb.Blueprint(rrb.Vertical(top, bottom, row_shares=[1.25, 1]), *side_panels(fps, focus))


def compare_blueprint(
    *,
    views: Sequence[str],
    encoders: Sequence[str],
    map_titles: Sequence[str],
    map_grids: Sequence[MapGrid],
    cells: Sequence[Cell],
    plots: Sequence[ScorePlots],
    fps: float = DEFAULT_FPS,
    signals: Sequence[str] = (),
) -> rrb.Blueprint:
    """Shared cameras and, per encoder, its own score plots (S_t and δ, C_t and γ, State_t), its map, nearest
    entries and report; the robot's `signals` (shared) a tab each."""
    detectors = [DetectorPaths.for_encoder(slug) for slug in encoders]
    top = rrb.Horizontal(
        _cameras(views),
        *(
            _score_plot(paths, views=views, plots=each, label=f"{slug} · ")
            for slug, paths, each in zip(encoders, detectors, plots, strict=True)
        ),
        column_shares=[0.9 * len(views), *([2.0] * len(encoders))],
    )
    maps = rrb.Horizontal(
        *(
            _map(paths, name=f"{slug} · {title}", grid=grid)
            for slug, paths, title, grid in zip(encoders, detectors, map_titles, map_grids, strict=True)
        )
    )
    nearest = rrb.Grid(
        *(
            view
            for slug, paths, cell in zip(encoders, detectors, cells, strict=True)
            for view in _neighbor_grids(views, 1, paths, cell, label=f"{slug} · ")
        ),
        grid_columns=len(views),
        name="nearest entries",
    )
    reports = [
        rrb.TextDocumentView(origin=paths.report, name=f"{slug} report")
        for slug, paths in zip(encoders, detectors, strict=True)
    ]
    events = rrb.TextLogView(
        origin="/", contents=[f"{paths.detection_root}/**" for paths in detectors], name="detection events"
    )
    tabs = rrb.Tabs(nearest, *reports, events, *signal_plots(signals), active_tab=0)
    bottom = rrb.Horizontal(maps, tabs, column_shares=[1, 1.2])
    return rrb.Blueprint(rrb.Vertical(top, bottom, row_shares=[1, 1.1]), *side_panels(fps))


def _closed_loop_score_plot(paths: DetectorPaths, *, name: str, length: int) -> rrb.Container:
    """S_t of every view with δ; State_t in a thin plot below; both span all L frames of the episode."""
    frames = rrb.TimeAxis(
        view_range=rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seq=0),
            end=rrb.TimeRangeBoundary.absolute(seq=length - 1),
        )
    )
    scores = rrb.TimeSeriesView(
        origin="/",
        contents=[f"{paths.score_root}/**"],
        name=name,
        axis_x=frames,
        plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.LeftBottom, visible=True),
    )
    state = rrb.TimeSeriesView(
        origin="/",
        contents=[paths.state],
        name="State_t (any view ≥ δ)",
        axis_x=frames,
        titlebar=False,  # its legend names it: the plot keeps its few pixels for the 0/1 line
        axis_y=rrb.ScalarAxis(range=(-0.1, 1.1), zoom_lock=True),
        plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.LeftTop, visible=True),
    )
    return rrb.Vertical(scores, state, row_shares=[3, 1.1])


def closed_loop_blueprint(
    *, views: Sequence[str], fps: float, length: int, focus: int | None = None, signals: Sequence[str] = ()
) -> rrb.Blueprint:
    """One row per run (cameras | S_t and State_t), the events, the outcome table and the robot's `signals`
    (both runs in one plot each) below."""
    rows = []
    for paths, title in ((WATCHED, "watched (stopped at the alarm)"), (UNSTOPPED, "unstopped")):
        cameras = rrb.Horizontal(
            *(rrb.Spatial2DView(origin=paths.camera(view), name=f"{paths.run} · {view}") for view in views)
        )
        plot = _closed_loop_score_plot(paths.detector, name=f"{title} · S_t per view and δ", length=length)
        rows.append(rrb.Horizontal(cameras, plot, column_shares=[len(views), 2.0]))
    events = rrb.TextLogView(
        origin="/",
        contents=[f"{paths.root}/**" for paths in (WATCHED, UNSTOPPED)],
        name="events (the alarm, the stop, each run's goal check)",
        columns=rrb.TextLogColumns(
            timeline_columns=[rrb.encodings.TimelineColumn(FRAME)],
            text_log_columns=[
                rrb.encodings.TextLogColumn("LogLevel"),
                rrb.encodings.TextLogColumn("Body"),
                rrb.encodings.TextLogColumn("EntityPath", visible=False),
            ],
        ),
    )
    summary = rrb.TextDocumentView(origin=CLOSED_LOOP_SUMMARY, name="outcome of both runs")
    robot = [
        rrb.TimeSeriesView(origin="/", contents=[WATCHED.signal(name), UNSTOPPED.signal(name)], name=name)
        for name in signals
    ]
    text = rrb.Horizontal(
        events,
        summary,
        *([rrb.Tabs(*robot, name="robot signals")] if robot else []),
        column_shares=[1, 1.1, 1.1][: 2 + bool(robot)],
    )
    return rrb.Blueprint(rrb.Vertical(*rows, text, row_shares=[1, 1, 0.85]), *side_panels(fps, focus))
