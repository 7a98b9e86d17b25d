"""The K nearest memory entries per view: start/end images logged only when a neighbour changes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import cv2
import numpy as np

from rfr_viz.panels.images import JPEG_MEDIA_TYPE, JPEG_QUALITY, ReferenceJpegs
from rfr_viz.paths import FRAME, TIME, DetectorPaths, NeighborPart
from robofailring.data.images import encode_jpeg
from robofailring.detection.detector import DetectionTrace
from robofailring.extras import needs_extra
from robofailring.memory.failure import MemoryEntry
from robofailring.memory.image_roots import ImageRoots

with needs_extra("viz"):
    import rerun as rr


@dataclass(frozen=True)
class NeighborImage:
    """A memory entry's reference image, JPEG-encoded once per recording."""

    jpeg: bytes
    width: int
    height: int


@dataclass(frozen=True)
class Cell:
    """Size of one image slot of the neighbour grid (rank r is row r: start | end)."""

    width: int
    height: int

    @property
    def gap(self) -> int:
        return max(2, self.width // 16)

    def rank_offset(self, rank: int) -> tuple[float, float]:
        return (0.0, float(rank * (self.height + self.gap)))

    @property
    def end_offset(self) -> tuple[float, float]:
        return (float(self.width + self.gap), 0.0)

    @property
    def top_row(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """x and y ranges of rank 0's start | end pair (the grid's default viewport)."""
        return (0.0, float(2 * self.width + self.gap)), (0.0, float(self.height))


DEFAULT_CELL: Final[Cell] = Cell(256, 256)
CHANGE_BATCH: Final[int] = 64
"""Neighbour changes logged between two flushes (each 3 rows: start and end JPEGs, info): a neighbour can
change at every frame, and rows left pending cost Rerun ~3.5 KB each (bench/bench_hdf5_memory.py)."""


class NeighborImages:
    """Reads and JPEG-encodes each referenced memory image once, only from under `roots` (the folders
    named for the memory's images, `FailureMemory.image_roots`); missing files and others are None."""

    def __init__(self, roots: ImageRoots) -> None:
        self._jpegs = ReferenceJpegs(roots)
        self._images: dict[str, NeighborImage | None] = {}

    def absence(self, reference: str) -> str:
        """Markdown naming an image not shown, and why (not found, or outside the roots)."""
        return self._jpegs.absence(reference)

    def get(self, reference: str) -> NeighborImage | None:
        if reference not in self._images:
            data = self._jpegs.get(reference)
            image = None
            if data is not None:
                decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
                if decoded is not None:
                    image = NeighborImage(data, width=decoded.shape[1], height=decoded.shape[0])
            self._images[reference] = image
        return self._images[reference]

    def cell(self, trace: DetectionTrace) -> Cell:
        """The largest image among the trace's neighbours (read now, reused when logging)."""
        used = np.unique(np.concatenate([trace.neighbor_ids[view].ravel() for view in trace.views]))
        sizes = [
            (image.width, image.height)
            for index in used
            if index >= 0
            for reference in (trace.memory.entries[int(index)].start, trace.memory.entries[int(index)].end)
            if (image := self.get(reference)) is not None
        ]
        if not sizes:
            return DEFAULT_CELL
        return Cell(max(w for w, _ in sizes), max(h for _, h in sizes))

    def placeholder(self, cell: Cell) -> bytes:
        """A grey JPEG saying "image not found", the size of one grid cell (made once per size)."""
        key = f"<missing:{cell.width}x{cell.height}>"
        cached = self._images.get(key)
        if cached is None:
            image = np.full((cell.height, cell.width, 3), 96, np.uint8)
            scale = max(cell.width, 64) / 256
            for line, text in enumerate(("image", "not found")):
                cv2.putText(
                    image,
                    text,
                    (max(2, cell.width // 10), int(cell.height * (0.45 + 0.2 * line))),
                    cv2.FONT_HERSHEY_SIMPLEX,
                    scale,
                    (255, 255, 255),
                    max(1, round(2 * scale)),
                    cv2.LINE_AA,
                )
            cached = NeighborImage(encode_jpeg(image, quality=JPEG_QUALITY), cell.width, cell.height)
            self._images[key] = cached
        return cached.jpeg


def changes(ids: np.ndarray) -> list[tuple[int, int, int]]:
    """(rank, t, entry index) wherever the rank-th neighbour differs from the previous frame."""
    found = []
    for rank in range(ids.shape[1]):
        column = ids[:, rank]
        starts = np.flatnonzero(np.concatenate([[True], column[1:] != column[:-1]]))
        found += [(rank, int(t), int(column[t])) for t in starts]
    return found


def neighbor_info(entry: MemoryEntry, rank: int, similarity: float, t: int) -> str:
    """Markdown: rank, similarity, task, symbol, view, episode, the moment of that run the entry's right-hand
    image is (a dense memory's frame, or the end of the run) and the grounded sentence."""
    return (
        f"**#{rank + 1}** · cos **{similarity:.3f}** at frame {t}  \n"
        f"`{entry.task}` · `{entry.symbol}` · {entry.view} · {entry.episode}  \n"
        f"matched: {entry.moment}  \n"
        f"{entry.description}"
    )


def no_failures_text(task: str) -> str:
    """Markdown for the neighbour panel of a task without failure entries (the novelty rule's)."""
    return (
        f"**No failure neighbours:** the memory holds no failure run of task `{task}` (success runs only).  \n"
        "It is judged by the novelty rule, N_t = 1 − S⁺_t ≥ η: see the nearest success frame."
    )


def log_no_failures(rec: rr.RecordingStream, paths: DetectorPaths, view: str, *, task: str) -> None:
    """A static text where a view's nearest failure would be: there is none to show."""
    rec.log(
        paths.neighbor(view, 0, "info"),
        rr.TextDocument(no_failures_text(task), media_type=rr.MediaType.MARKDOWN),
        static=True,
    )


def _parts(entry: MemoryEntry) -> tuple[tuple[NeighborPart, str], ...]:
    return (("start", entry.start), ("end", entry.end))


def log_neighbors(
    rec: rr.RecordingStream,
    trace: DetectionTrace,
    paths: DetectorPaths,
    *,
    fps: float,
    images: NeighborImages,
    cell: Cell,
) -> None:
    """`/neighbors/<view>/<rank>/{start,end,info}` at the frames where that neighbour changes.

    Ranks are laid out as a grid (row = rank, start | end) by static translations, so one 2-D view
    per camera view holds all K. The info is re-sent at t_det so it shows the similarity that fired.
    A task without failure entries gets a text saying so instead (`log_no_failures`).
    """
    if not trace.has_failures:
        for view in trace.views:
            log_no_failures(rec, paths, view, task=trace.task)
        return
    for view in trace.views:
        ids = trace.neighbor_ids[view]
        log_neighbor_layout(rec, paths, view, k=ids.shape[1], cell=cell)
        scored = trace.scored_frames  # with a stride, neighbours exist only at scored frames
        for count, (rank, step, index) in enumerate(changes(ids[scored]), start=1):
            if count % CHANGE_BATCH == 0:
                rec.flush()
            t = int(scored[step])
            rec.set_time(FRAME, sequence=t)
            rec.set_time(TIME, duration=t / fps)
            if index < 0:
                rec.log(paths.neighbor_rank(view, rank), rr.Clear(recursive=True))
                continue
            entry = trace.memory.entries[index]
            similarity = float(trace.neighbor_similarity[view][t, rank])
            log_neighbor_entry(
                rec, paths, view, rank, entry, similarity=similarity, t=t, images=images, cell=cell
            )
    t_det = trace.t_det
    if t_det is None:
        return
    rec.set_time(FRAME, sequence=t_det)
    rec.set_time(TIME, duration=t_det / fps)
    for view in trace.views:
        for rank, index in enumerate(trace.neighbor_ids[view][t_det]):
            if index >= 0:
                entry = trace.memory.entries[int(index)]
                similarity = float(trace.neighbor_similarity[view][t_det, rank])
                _log_info(rec, paths, view, rank, entry, similarity, t_det, _missing(entry, images))


def _missing(entry: MemoryEntry, images: NeighborImages) -> list[str]:
    return [images.absence(reference) for _, reference in _parts(entry) if images.get(reference) is None]


def log_neighbor_layout(
    rec: rr.RecordingStream, paths: DetectorPaths, view: str, *, k: int, cell: Cell
) -> None:
    """Static translations that lay a view's K neighbours out as a grid (row = rank, start | end)."""
    for rank in range(k):
        rec.log(
            paths.neighbor_rank(view, rank),
            rr.Transform3D(translation=[*cell.rank_offset(rank), 0.0]),
            static=True,
        )
        rec.log(
            paths.neighbor(view, rank, "end"),
            rr.Transform3D(translation=[*cell.end_offset, 0.0]),
            static=True,
        )


def log_neighbor_entry(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    view: str,
    rank: int,
    entry: MemoryEntry,
    *,
    similarity: float,
    t: int,
    images: NeighborImages,
    cell: Cell,
) -> None:
    """The rank-th neighbour of a view became `entry` (at the current time): its images and info.

    An image that cannot be found shows as a grey "image not found" tile, and the info names it.
    """
    for part, reference in _parts(entry):
        image = images.get(reference)
        rec.log(
            paths.neighbor(view, rank, part),
            rr.EncodedImage(
                contents=image.jpeg if image is not None else images.placeholder(cell),
                media_type=JPEG_MEDIA_TYPE,
            ),
        )
    _log_info(rec, paths, view, rank, entry, similarity, t, _missing(entry, images))


def _log_info(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    view: str,
    rank: int,
    entry: MemoryEntry,
    similarity: float,
    t: int,
    missing: list[str],
) -> None:
    text = neighbor_info(entry, rank, similarity, t)
    if missing:
        text += "".join(f"  \n{absence}" for absence in missing)
    rec.log(
        paths.neighbor(view, rank, "info"),
        rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN),
        rr.TextLog(
            f"{view} #{rank + 1}: {entry.symbol} ({entry.task}/{entry.episode} [{entry.view}], {entry.moment}) "
            f"cos {similarity:.3f}",
            level="INFO",
        ),
    )
