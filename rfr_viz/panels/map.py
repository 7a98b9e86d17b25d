"""The memory-map panel: one map per view coloured by failure type, side by side, a legend, each view's moving query."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np

from rfr_viz.panels.scores import time_columns
from rfr_viz.panels.umap import MemoryMap
from rfr_viz.paths import DetectorPaths
from rfr_viz.styles import FAILURE_CLASSES, MAP_FRAME_COLOUR, UNKNOWN_CLASS, VIEW_COLOURS
from robofailring.data.grounding import Vocabulary, failure_type
from robofailring.detection.detector import DetectionTrace, Place
from robofailring.errors import SymbolError
from robofailring.extras import needs_extra
from robofailring.memory.failure import MemoryEntry

with needs_extra("viz"):
    import rerun as rr

LABELLED_ENTRIES_MAX: Final[int] = 5_000  # larger memories label only the replayed task's map points
PITCH: Final[float] = 2.4  # between the centres of two views' maps, which span [-1, 1]² each
FRAME: Final[float] = 1.1  # half the side of the box around a view's map
TITLE: Final[float] = 0.25  # the strip at the top of a view's box that holds its name
LEGEND_ROW: Final[float] = 0.22
LEGEND_CELL_ROWS: Final[int] = 8  # a legend in a free grid cell: columns of this many entries
MAP_MARGIN: Final[float] = 0.1


@dataclass(frozen=True)
class MapGrid:
    """Where each view's map sits in the memory-map panel: a grid of about √n columns, the legend in the
    first free cell, or in a strip below when the grid is full."""

    views: int
    legend_entries: int

    @property
    def columns(self) -> int:
        return max(1, math.ceil(math.sqrt(self.views)))

    @property
    def rows(self) -> int:
        return max(1, math.ceil(self.views / self.columns))

    @property
    def legend_in_cell(self) -> bool:
        return self.views < self.rows * self.columns

    def offset(self, position: int) -> tuple[float, float]:
        """The centre of the position-th view's map (y grows downwards, as in a Rerun 2-D view)."""
        return (position % self.columns) * PITCH, (position // self.columns) * (PITCH + TITLE)

    def legend_positions(self) -> np.ndarray:
        """(legend_entries, 2) positions of the legend's entries (each a dot with its label)."""
        slots = np.arange(self.legend_entries)
        if self.legend_in_cell:
            x, y = self.offset(self.views)
            columns = max(1, math.ceil(self.legend_entries / LEGEND_CELL_ROWS))
            return np.stack(
                [
                    x + (slots // LEGEND_CELL_ROWS - (columns - 1) / 2) * (2 * FRAME / columns),
                    y - FRAME - TITLE + LEGEND_ROW * (0.75 + slots % LEGEND_CELL_ROWS),
                ],
                axis=1,
            )
        per_row = 2 * self.columns
        return np.stack(
            [
                -PITCH / 4 + (slots % per_row) * PITCH / 2,
                self._legend_top() + (slots // per_row) * LEGEND_ROW,
            ],
            axis=1,
        )

    def _legend_top(self) -> float:
        return (self.rows - 1) * (PITCH + TITLE) + FRAME + 0.3

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The panel's visual bounds: every map, its box and label, and the legend."""
        right = (self.columns - 1) * PITCH + FRAME + MAP_MARGIN
        bottom = (self.rows - 1) * (PITCH + TITLE) + FRAME + MAP_MARGIN
        if not self.legend_in_cell and self.legend_entries:
            rows = math.ceil(self.legend_entries / (2 * self.columns))
            bottom = self._legend_top() + (rows - 0.5) * LEGEND_ROW + MAP_MARGIN
        return (-FRAME - MAP_MARGIN, right), (-FRAME - TITLE - MAP_MARGIN, bottom)


def class_id(symbol: str, vocabulary: Vocabulary | None = None) -> int:
    """The map class of a failure symbol: its Table 5 failure type, 0 when unknown (also a `vocabulary`'s own)."""
    try:
        kind = failure_type(symbol, vocabulary)
    except SymbolError:
        return UNKNOWN_CLASS[0]
    return FAILURE_CLASSES[kind][0] if kind in FAILURE_CLASSES else UNKNOWN_CLASS[0]


def annotation_context() -> rr.AnnotationContext:
    """Failure type -> class id, label and colour of the memory map."""
    classes = [rr.ClassDescription(info=UNKNOWN_CLASS)]
    classes += [rr.ClassDescription(info=(cid, kind, rgb)) for kind, (cid, rgb) in FAILURE_CLASSES.items()]
    return rr.AnnotationContext(classes)


def map_labels(entries: Sequence[MemoryEntry], *, task: str) -> list[str]:
    """Hover labels "task · symbol · view · episode" of the map's points (a dense entry adds its frame,
    "· frame 34/40").

    Up to LABELLED_ENTRIES_MAX entries all are labelled; in larger memories only the replayed task's
    entries (the only ones the detector can retrieve), the others show their failure type (class) on
    hover: labels would otherwise cost ~16 bytes per entry in every recording.
    """
    everyone = len(entries) <= LABELLED_ENTRIES_MAX
    return [
        f"{e.task} · {e.symbol} · {e.view} · {e.episode}"
        + (f" · frame {e.frame}/{e.length}" if e.frame is not None else "")
        if everyone or e.task == task
        else ""
        for e in entries
    ]


def log_memory_map(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    *,
    entries: Sequence[MemoryEntry],
    memory_map: MemoryMap,
    task: str,
    views: Sequence[str],
) -> None:
    """The static maps, one per view of the memory (classes = failure types, hover labels), the legend, and
    a query marker for each of `views` (the trajectory's) that has a map."""
    classes = np.asarray([class_id(entry.symbol, entry.vocabulary) for entry in entries], dtype=np.uint16)
    labels = np.asarray(map_labels(entries, task=task), dtype=object)
    grid = map_grid(memory_map, classes)
    rec.log(paths.map_root, annotation_context(), static=True)
    for position, (view, view_map) in enumerate(memory_map.maps.items()):
        rows = memory_map.rows[view]
        x, y = grid.offset(position)
        rec.log(paths.umap(view), rr.Transform3D(translation=[x, y, 0.0]), static=True)
        rec.log(
            paths.umap(view),
            rr.Points2D(
                view_map.embedding,
                class_ids=classes[rows],
                labels=labels[rows].tolist(),
                show_labels=False,
                radii=rr.Radius.ui_points(3.0),
            ),
            static=True,
        )
        rec.log(
            paths.umap_frame(view),
            rr.Boxes2D(
                mins=[[-FRAME, -FRAME - TITLE]],
                sizes=[[2 * FRAME, 2 * FRAME + TITLE]],
                colors=[MAP_FRAME_COLOUR],
                radii=rr.Radius.ui_points(0.75),
            ),
            static=True,
        )
        rec.log(  # a point's label follows its entity's transform (a box's does not, in Rerun 0.41)
            paths.umap_title(view),
            rr.Points2D(
                [[0.0, -FRAME - TITLE]],
                labels=[f"{view} · {len(rows)} entries"],
                show_labels=True,
                colors=[MAP_FRAME_COLOUR],
                radii=rr.Radius.ui_points(0.0),
            ),
            static=True,
        )
    _log_legend(rec, paths, classes, grid)
    for position, view in enumerate(views):
        if view not in memory_map.maps:
            continue
        rec.log(
            paths.umap_query(view),
            rr.Points2D.from_fields(
                colors=[VIEW_COLOURS[position % len(VIEW_COLOURS)]],
                radii=rr.Radius.ui_points(6.0),
                labels=["now"],
                show_labels=True,
                draw_order=100.0,
            ),
            static=True,
        )


def placer(memory_map: MemoryMap, task: str) -> Place:
    """The `place` of `FailureDetector.run` that keeps each query of `task` as its point in its view's
    map, not its vector (NaN rows for a view the memory has no entries of)."""

    def place(view: str, queries: np.ndarray) -> np.ndarray:
        placed = memory_map.project(view, task, queries)
        return placed if placed is not None else np.full((len(queries), 2), np.nan, np.float32)

    return place


def log_map(
    rec: rr.RecordingStream, trace: DetectionTrace, paths: DetectorPaths, memory_map: MemoryMap, fps: float
) -> None:
    """The static maps and each view's query, moving with time inside its view's map (from
    `trace.placed` when `run(place=placer(memory_map, task))` made the trace, else from `trace.queries`)."""
    log_memory_map(
        rec, paths, entries=trace.memory.entries, memory_map=memory_map, task=trace.task, views=trace.views
    )
    scored = trace.scored_frames  # the query moves only at scored frames (every `stride`-th)
    for view in trace.views:
        if view in trace.placed:
            placed = trace.placed[view]
            if np.isnan(placed).all():  # the memory has no entries of this view
                continue
        else:
            projected = memory_map.project(view, trace.task, trace.queries[view])
            if projected is None:
                continue
            placed = projected
        rec.send_columns(
            paths.umap_query(view),
            indexes=time_columns(scored, fps),
            columns=rr.Points2D.columns(positions=placed).partition(np.ones(len(scored), dtype=np.int64)),
        )


def _log_legend(rec: rr.RecordingStream, paths: DetectorPaths, classes: np.ndarray, grid: MapGrid) -> None:
    """The legend: the failure types present, with their counts, in a free grid cell or below the maps."""
    present, counts = np.unique(classes, return_counts=True)
    names = {cid: kind for kind, (cid, _) in FAILURE_CLASSES.items()} | {UNKNOWN_CLASS[0]: UNKNOWN_CLASS[1]}
    colours = {cid: rgb for cid, rgb in FAILURE_CLASSES.values()} | {UNKNOWN_CLASS[0]: UNKNOWN_CLASS[2]}
    labels = [f"{names[int(cid)]} ({count})" for cid, count in zip(present, counts, strict=True)]
    rgb = [colours[int(cid)] for cid in present]
    rec.log(
        paths.map_legend,
        rr.Points2D(
            grid.legend_positions(),
            colors=rgb,
            labels=labels,
            show_labels=True,
            radii=rr.Radius.ui_points(4.0),
        ),
        static=True,
    )


def map_grid(memory_map: MemoryMap, classes: np.ndarray | Sequence[int]) -> MapGrid:
    """The panel's grid: one cell per view of the memory, a legend entry per failure type present."""
    return MapGrid(views=len(memory_map.maps), legend_entries=len(set(np.asarray(classes).tolist())))


def trace_map_grid(trace: DetectionTrace, memory_map: MemoryMap) -> MapGrid:
    """The grid of a replayed trace's map panel (what its blueprint's bounds need)."""
    return map_grid(memory_map, [class_id(entry.symbol, entry.vocabulary) for entry in trace.memory.entries])


def map_title(memory_map: MemoryMap) -> str:
    """The map view's title, which says how the map was made (UMAP, or the PCA fallback)."""
    what = "PCA" if memory_map.method == "pca" else "UMAP"
    return f"memory map per view ({what}, {memory_map.size})"
