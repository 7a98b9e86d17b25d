"""The memory-map panel: the memory's UMAP coloured by failure type, a legend, and each view's moving query."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import numpy as np

from rfr_viz.panels.scores import time_columns
from rfr_viz.panels.umap import MemoryMap
from rfr_viz.paths import DetectorPaths
from rfr_viz.styles import FAILURE_CLASSES, UNKNOWN_CLASS, VIEW_COLOURS
from robofailring.data.grounding import Vocabulary, failure_type
from robofailring.detection.detector import DetectionTrace, Place
from robofailring.errors import SymbolError
from robofailring.extras import needs_extra
from robofailring.memory.failure import MemoryEntry

with needs_extra("viz"):
    import rerun as rr

LABELLED_ENTRIES_MAX: Final[int] = 5_000  # larger memories label only the replayed task's map points


LEGEND_TOP = 1.3  # the map spans [-1, 1]²; its legend sits below it, two entries per row
LEGEND_ROW = 0.2
LEGEND_COLUMN = 0.62


def legend_positions(count: int) -> np.ndarray:
    """(count, 2) positions of the map legend's entries, in map coordinates."""
    slots = np.arange(count)
    return np.stack(
        [np.where(slots % 2 == 0, -LEGEND_COLUMN, LEGEND_COLUMN), LEGEND_TOP + (slots // 2) * LEGEND_ROW],
        axis=1,
    )


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
    """Hover labels "task · symbol · view · episode" of the map's points.

    Up to LABELLED_ENTRIES_MAX entries all are labelled; in larger memories only the replayed task's
    entries (the only ones the detector can retrieve), the others show their failure type (class) on
    hover: labels would otherwise cost ~16 bytes per entry in every recording.
    """
    everyone = len(entries) <= LABELLED_ENTRIES_MAX
    return [
        f"{e.task} · {e.symbol} · {e.view} · {e.episode}" if everyone or e.task == task else ""
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
    """The static memory map (classes = failure types, hover labels, legend) and each view's query marker."""
    classes = np.asarray([class_id(entry.symbol, entry.vocabulary) for entry in entries], dtype=np.uint16)
    rec.log(paths.umap, annotation_context(), static=True)
    rec.log(
        paths.umap,
        rr.Points2D(
            memory_map.embedding,
            class_ids=classes,
            labels=map_labels(entries, task=task),
            show_labels=False,
            radii=rr.Radius.ui_points(3.0),
        ),
        static=True,
    )
    _log_legend(rec, paths, classes)
    for position, view in enumerate(views):
        rec.log(
            paths.umap_query(view),
            rr.Points2D.from_fields(
                colors=[VIEW_COLOURS[position % len(VIEW_COLOURS)]],
                radii=rr.Radius.ui_points(6.0),
                labels=[f"now: {view}"],
                show_labels=True,
                draw_order=100.0,
            ),
            static=True,
        )


def placer(memory_map: MemoryMap) -> Place:
    """The `place` of `FailureDetector.run` that keeps each query as its point on this map, not its vector."""
    return lambda view, queries: memory_map.project(queries)


def log_map(
    rec: rr.RecordingStream, trace: DetectionTrace, paths: DetectorPaths, memory_map: MemoryMap, fps: float
) -> None:
    """The static memory map and each view's query, moving with time (from `trace.placed` when
    `run(place=placer(memory_map))` made the trace, else projected from `trace.queries`)."""
    log_memory_map(
        rec, paths, entries=trace.memory.entries, memory_map=memory_map, task=trace.task, views=trace.views
    )
    scored = trace.scored_frames  # the query moves only at scored frames (every `stride`-th)
    for view in trace.views:
        placed = trace.placed[view] if view in trace.placed else memory_map.project(trace.queries[view])
        rec.send_columns(
            paths.umap_query(view),
            indexes=time_columns(scored, fps),
            columns=rr.Points2D.columns(positions=placed).partition(np.ones(len(scored), dtype=np.int64)),
        )


def _log_legend(rec: rr.RecordingStream, paths: DetectorPaths, classes: np.ndarray) -> None:
    """A legend under the map (which spans [-1, 1]²): the failure types present, with their counts."""
    present, counts = np.unique(classes, return_counts=True)
    names = {cid: kind for kind, (cid, _) in FAILURE_CLASSES.items()} | {UNKNOWN_CLASS[0]: UNKNOWN_CLASS[1]}
    colours = {cid: rgb for cid, rgb in FAILURE_CLASSES.values()} | {UNKNOWN_CLASS[0]: UNKNOWN_CLASS[2]}
    labels = [f"{names[int(cid)]} ({count})" for cid, count in zip(present, counts, strict=True)]
    rgb = [colours[int(cid)] for cid in present]
    rec.log(
        f"{paths.umap}/legend",
        rr.Points2D(
            legend_positions(len(labels)),
            colors=rgb,
            labels=labels,
            show_labels=True,
            radii=rr.Radius.ui_points(4.0),
        ),
        static=True,
    )


def legend_size(trace: DetectionTrace) -> int:
    """Entries of the map legend: the failure types present in the memory."""
    return len({class_id(entry.symbol, entry.vocabulary) for entry in trace.memory.entries})


def map_title(memory_map: MemoryMap) -> str:
    """The map view's title, which says how the map was made (UMAP, or the PCA fallback)."""
    if memory_map.method == "umap":
        return f"memory map · UMAP (cosine) of {len(memory_map.embedding)} entries"
    return f"memory map · PCA ({len(memory_map.embedding)} entries, too few for UMAP)"
