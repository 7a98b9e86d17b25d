"""Replayed trajectories as `.rrd` recordings (README, "The recording layout"): one file per trajectory, blueprint inside."""

from __future__ import annotations

import re
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from rfr_viz.blueprint import compare_blueprint, legend_positions, replay_blueprint
from rfr_viz.camera_video import CameraCodec, log_camera_views
from rfr_viz.contrast import log_contrast
from rfr_viz.memory_umap import MemoryMap, fit_map
from rfr_viz.neighbors import Cell, NeighborImages, log_neighbors
from rfr_viz.paths import APPLICATION_ID, DEFAULT_FPS, FRAME, PROPERTIES, REPLAY, TIME, DetectorPaths
from robofailring.atomic import atomic_path
from robofailring.data.model import Trajectory
from robofailring.detector import DetectionTrace
from robofailring.errors import SymbolError
from robofailring.grounding import failure_type
from robofailring.memory import MemoryEntry, Neighbor
from robofailring.report import FailureReport, report_for
from robofailring.scoring import ScoreRule
from robofailring.vlm import VLMAnswer

#: Failure types of grounding (Table 5) as map classes with fixed colours; class 0 is "unknown".
FAILURE_CLASSES: Final[dict[str, tuple[int, tuple[int, int, int]]]] = {
    "rotation": (1, (230, 85, 70)),
    "translation": (2, (70, 150, 240)),
    "grasp": (3, (250, 190, 40)),
    "slip": (4, (170, 110, 230)),
    "no_rotation": (5, (60, 200, 120)),
    "wrong_sequence": (6, (240, 120, 200)),
    "wrong_object": (7, (150, 210, 230)),
}
UNKNOWN_CLASS: Final[tuple[int, str, tuple[int, int, int]]] = (0, "unknown", (150, 150, 150))
VIEW_COLOURS: Final[tuple[tuple[int, int, int], ...]] = (
    (80, 160, 255),
    (90, 210, 110),
    (255, 160, 60),
    (200, 120, 255),
    (240, 220, 80),
)
ENCODER_COLOURS: Final[tuple[tuple[int, int, int], ...]] = ((80, 160, 255), (255, 150, 60), (90, 210, 110))
DELTA_COLOUR: Final[tuple[int, int, int]] = (235, 60, 60)
STATE_COLOUR: Final[tuple[int, int, int]] = (170, 170, 170)
#: Few, large chunks: every chunk carries its own schema, so many small ones would dominate the file.
BATCHING: Final[rr.ChunkBatcherConfig] = rr.ChunkBatcherConfig(
    flush_tick=60.0, flush_num_bytes=4 * 1024 * 1024
)
LABELLED_ENTRIES_MAX: Final[int] = 5_000  # larger memories label only the replayed task's map points
_MARKDOWN_IMAGE = re.compile(r"!\[([^\]]*)\]\(([^)]*)\)")


@dataclass(frozen=True)
class RecordingInfo:
    """What a recording says about the trajectory itself (shared by every encoder)."""

    task: str
    episode: str
    label: str
    outcome: str
    fps: float

    @classmethod
    def of(cls, trajectory: Trajectory, *, fps: float | None = None) -> RecordingInfo:
        return cls(
            task=trajectory.task,
            episode=trajectory.episode,
            label=trajectory.label,
            outcome=trajectory.outcome.value if trajectory.outcome is not None else "unknown",
            fps=float(fps or trajectory.fps or DEFAULT_FPS),
        )


def record_replay(
    trajectory: Trajectory,
    trace: DetectionTrace,
    *,
    out: Path,
    memory_map: MemoryMap | None = None,
    fps: float | None = None,
    recording_id: str | None = None,
    focus_frame: int | None = None,
    vlm_answer: VLMAnswer | None = None,
    camera_codec: CameraCodec | str = CameraCodec.JPEG,
) -> Path:
    """Write one replayed trajectory as a self-contained `.rrd` at `out`, atomically.

    `focus_frame` makes the recording open playing around that frame (e.g. a false alarm).
    `vlm_answer` (what a VLM said about the failure report) is added to the report at t_det.

    `camera_codec` stores the cameras as JPEGs, AV1 or H.264 video, or `auto` (by size; rfr_viz.camera_video).
    `memory_map` is the memory's cached map (`rfr_viz.memory_map(memory, directory=...)`); without
    one it is fitted here, uncached. `fps` drives the "time" timeline (default: the data's, else 10).
    """
    info = RecordingInfo.of(trajectory, fps=fps)
    mapped = memory_map if memory_map is not None else fit_map(trace.memory.vectors)
    images = NeighborImages()
    cell = images.cell(trace)
    blueprint = replay_blueprint(
        views=trace.views,
        map_title=map_title(mapped),
        legend_entries=legend_size(trace),
        cell=cell,
        k=trace.k,
        fps=info.fps,
        focus=focus_frame,
        contrast=bool(trace.success_similarity),
    )
    with open_recording(out, blueprint, recording_id=recording_id) as rec:
        rec.send_recording_name(f"{info.task}/{info.episode}")
        rec.send_property(
            PROPERTIES,
            rr.AnyValues(
                **_trajectory_properties(info, trace.length),
                **_detector_properties(trace, mapped),
                focus_frame=focus_frame if focus_frame is not None else -1,  # -1: none (see rfr_viz.viewer)
                **_report_properties(trace, trajectory, vlm_answer),
            ),
        )
        log_cameras(rec, trajectory, views=trace.views, length=trace.length, fps=info.fps, codec=camera_codec)
        log_detector(
            rec,
            trace,
            paths=REPLAY,
            memory_map=mapped,
            fps=info.fps,
            trajectory=trajectory,
            images=images,
            cell=cell,
            vlm_answer=vlm_answer,
        )
    return Path(out)


def compare_recording(
    trajectory: Trajectory,
    traces: Mapping[str, DetectionTrace],
    *,
    out: Path,
    memory_maps: Mapping[str, MemoryMap] | None = None,
    fps: float | None = None,
    recording_id: str | None = None,
    camera_codec: CameraCodec | str = CameraCodec.JPEG,
) -> Path:
    """One recording of a trajectory replayed under several encoders, `traces` keyed by encoder slug.

    Cameras are shared at `/camera/<view>`; everything that depends on the detector lives under
    `/<slug>/…`, and all S_t curves and δ lines share one plot.
    """
    if not traces:
        raise ValueError("compare_recording needs at least one trace")
    info = RecordingInfo.of(trajectory, fps=fps)
    slugs = list(traces)
    maps = {
        slug: (memory_maps or {}).get(slug) or fit_map(trace.memory.vectors) for slug, trace in traces.items()
    }
    images = NeighborImages()
    cells = {slug: images.cell(trace) for slug, trace in traces.items()}
    views = list(dict.fromkeys(view for trace in traces.values() for view in trace.views))
    length = max(trace.length for trace in traces.values())
    blueprint = compare_blueprint(
        views=views,
        encoders=slugs,
        map_titles=[map_title(maps[slug]) for slug in slugs],
        legend_entries=[legend_size(traces[slug]) for slug in slugs],
        cells=[cells[slug] for slug in slugs],
        fps=info.fps,
        contrast=any(trace.success_similarity for trace in traces.values()),
    )
    with open_recording(out, blueprint, recording_id=recording_id) as rec:
        rec.send_recording_name(f"{info.task}/{info.episode} ({' vs '.join(slugs)})")
        rec.send_property(
            PROPERTIES,
            rr.AnyValues(
                **_trajectory_properties(info, length),
                encoder=", ".join(trace.encoder for trace in traces.values()),
                encoders=", ".join(slugs),
            ),
        )
        log_cameras(rec, trajectory, views=views, length=length, fps=info.fps, codec=camera_codec)
        for position, (slug, trace) in enumerate(traces.items()):
            rec.send_property(slug, rr.AnyValues(**_detector_properties(trace, maps[slug])))
            log_detector(
                rec,
                trace,
                paths=DetectorPaths.for_encoder(slug),
                memory_map=maps[slug],
                fps=info.fps,
                trajectory=trajectory,
                images=images,
                cell=cells[slug],
                label=slug,
                colour=ENCODER_COLOURS[position % len(ENCODER_COLOURS)],
            )
    return Path(out)


@contextmanager
def open_recording(
    out: Path, blueprint: rrb.Blueprint, *, recording_id: str | None
) -> Iterator[rr.RecordingStream]:
    """A recording saved to a temporary file that becomes `out` only if the block succeeds."""
    with atomic_path(Path(out), suffix=".rrd") as tmp:
        rec = rr.RecordingStream(
            APPLICATION_ID, recording_id=recording_id or str(uuid.uuid4()), batcher_config=BATCHING
        )
        rec.set_log_time_enabled(False)  # a replay has its own timelines; wall-clock time adds nothing
        with rec:  # leaving the block flushes and closes the file sink, also on error
            rec.save(tmp, default_blueprint=blueprint)
            yield rec


def legend_size(trace: DetectionTrace) -> int:
    """Entries of the map legend: the failure types present in the memory."""
    return len({class_id(entry.symbol) for entry in trace.memory.entries})


def map_title(memory_map: MemoryMap) -> str:
    """The map view's title, which says how the map was made (UMAP, or the PCA fallback)."""
    if memory_map.method == "umap":
        return f"memory map · UMAP (cosine) of {len(memory_map.embedding)} entries"
    return f"memory map · PCA ({len(memory_map.embedding)} entries, too few for UMAP)"


def _trajectory_properties(info: RecordingInfo, length: int) -> dict[str, Any]:
    return {
        "task": info.task,
        "episode": info.episode,
        "label": info.label,
        "outcome": info.outcome,
        "L": length,
        "fps": info.fps,
    }


def _report_properties(
    trace: DetectionTrace, trajectory: Trajectory, vlm_answer: VLMAnswer | None
) -> dict[str, Any]:
    """The failure report as JSON (what `robofailring explain` reads back; absent without a detection)
    and, when a VLM was asked, its model and answer or error."""
    report = report_for(trace, trajectory)
    found: dict[str, Any] = {"report": report.to_json()} if report is not None else {}
    if vlm_answer is not None:
        found["vlm_model"] = vlm_answer.model
        found["vlm_answer" if vlm_answer.error is None else "vlm_error"] = (
            vlm_answer.answer or vlm_answer.error
        )
    return found


def _detector_properties(trace: DetectionTrace, memory_map: MemoryMap) -> dict[str, Any]:
    return {
        "encoder": trace.encoder,
        "delta": float(trace.delta),
        "score": trace.rule.value,
        "threshold": float(trace.threshold),
        "gamma": float(trace.gamma),
        "success_entries": len(trace.memory.successes) if trace.memory.successes is not None else 0,
        "k": trace.k,
        "t_det": trace.t_det if trace.t_det is not None else -1,  # -1: the detector never fired
        "detected_view": trace.detected_view or "",
        "views": ", ".join(trace.views),
        "skipped_views": ", ".join(trace.skipped_views),
        "unscored_frames": ", ".join(f"{view}: {count}" for view, count in trace.truncated_views.items()),
        "stride": trace.stride,  # frames 0, stride, 2·stride, … were scored; every camera frame is kept
        "memory_entries": len(trace.memory),
        "map": memory_map.method,
        "map_note": memory_map.note,
    }


def time_columns(frames: np.ndarray, fps: float) -> list[rr.TimeColumn]:
    """The two timelines of a batch of frames: "frame" (sequence) and "time" (seconds)."""
    return [
        rr.TimeColumn(FRAME, sequence=frames),
        rr.TimeColumn(TIME, duration=frames.astype(np.float64) / fps),
    ]


def set_frame_time(rec: rr.RecordingStream, t: int, fps: float) -> None:
    rec.set_time(FRAME, sequence=t)
    rec.set_time(TIME, duration=t / fps)


def log_cameras(
    rec: rr.RecordingStream,
    trajectory: Trajectory,
    *,
    views: Sequence[str],
    length: int,
    fps: float,
    codec: CameraCodec | str = CameraCodec.JPEG,
) -> None:
    """`/camera/<view>`: JPEG per frame, or AV1/H.264 video (rfr_viz.camera_video), never raw pixels."""
    indexes = lambda frames: time_columns(frames, fps)  # noqa: E731
    log_camera_views(rec, trajectory, views=views, length=length, indexes=indexes, codec=codec)


def log_detector(
    rec: rr.RecordingStream,
    trace: DetectionTrace,
    *,
    paths: DetectorPaths,
    memory_map: MemoryMap,
    fps: float,
    trajectory: Trajectory | None = None,
    images: NeighborImages | None = None,
    cell: Cell | None = None,
    label: str | None = None,
    colour: tuple[int, int, int] | None = None,
    vlm_answer: VLMAnswer | None = None,
) -> None:
    """Everything that depends on the detector: scores, δ, state, map, neighbours, event and report."""
    images = images or NeighborImages()
    _log_scores(rec, trace, paths, fps, label=label, colour=colour)
    view_colours = (
        [_shade(colour, i, len(trace.views)) for i in range(len(trace.views))]
        if colour
        else list(VIEW_COLOURS)
    )
    log_contrast(rec, trace, paths, fps=fps, colours=view_colours, prefix=f"{label} · " if label else "")
    _log_map(rec, trace, paths, memory_map, fps)
    log_neighbors(rec, trace, paths, fps=fps, images=images, cell=cell or images.cell(trace))
    _log_detection(rec, trace, paths, fps, trajectory, vlm_answer)


def _shade(colour: tuple[int, int, int], position: int, count: int) -> tuple[int, int, int]:
    """Views of one encoder in a comparison: its hue, from full strength to lighter."""
    mix = 0.6 * position / max(count - 1, 1)
    red, green, blue = (int(c + (255 - c) * mix) for c in colour)
    return red, green, blue


def log_score_styles(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    *,
    views: Sequence[str],
    delta: float,
    rule: ScoreRule = ScoreRule.PAPER,
    label: str | None = None,
    colour: tuple[int, int, int] | None = None,
) -> None:
    """Static line styles of S⁻_t per view, δ and State_t under `rule` (names, colours, widths)."""
    prefix = f"{label} · " if label else ""
    for position, view in enumerate(views):
        view_colour = (
            _shade(colour, position, len(views)) if colour else VIEW_COLOURS[position % len(VIEW_COLOURS)]
        )
        rec.log(
            paths.score(view),
            rr.SeriesLines(colors=[view_colour], widths=[2.0], names=[f"{prefix}{view} S⁻ (failure)"]),
            static=True,
        )
    delta_colour = DELTA_COLOUR if colour is None else _shade(colour, 0, 1)
    rec.log(
        paths.delta,
        rr.SeriesLines(colors=[delta_colour], widths=[1.0], names=[f"{prefix}δ = {delta:.3f}"]),
        static=True,
    )
    rec.log(
        paths.state,
        rr.SeriesLines(
            colors=[STATE_COLOUR if colour is None else colour],
            widths=[1.5],
            names=[f"{prefix}State_t ({rule.value}: any view {rule.score_name} ≥ {rule.symbol})"],
        ),
        static=True,
    )


def _log_scores(
    rec: rr.RecordingStream,
    trace: DetectionTrace,
    paths: DetectorPaths,
    fps: float,
    *,
    label: str | None,
    colour: tuple[int, int, int] | None,
) -> None:
    log_score_styles(
        rec, paths, views=trace.views, delta=trace.delta, rule=trace.rule, label=label, colour=colour
    )
    for view in trace.views:
        similarity = np.asarray(trace.similarity[view], dtype=np.float64)
        present = np.flatnonzero(np.isfinite(similarity))
        rec.send_columns(
            paths.score(view),
            indexes=time_columns(present, fps),
            columns=rr.Scalars.columns(scalars=similarity[present]),
        )
    frames = np.arange(trace.length)
    rec.send_columns(
        paths.delta,
        indexes=time_columns(frames, fps),
        columns=rr.Scalars.columns(scalars=np.full(trace.length, float(trace.delta))),
    )
    scored = trace.scored_frames  # with a stride, State_t exists only where frames were scored
    rec.send_columns(
        paths.state,
        indexes=time_columns(scored, fps),
        columns=rr.Scalars.columns(scalars=trace.state[scored].astype(np.float64)),
    )


def class_id(symbol: str) -> int:
    """The map class of a failure symbol: its failure type (grounding Table 5), 0 when unknown."""
    try:
        kind = failure_type(symbol)
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
    classes = np.asarray([class_id(entry.symbol) for entry in entries], dtype=np.uint16)
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


def _log_map(
    rec: rr.RecordingStream, trace: DetectionTrace, paths: DetectorPaths, memory_map: MemoryMap, fps: float
) -> None:
    """The static memory map and each view's query, moving with time."""
    log_memory_map(
        rec, paths, entries=trace.memory.entries, memory_map=memory_map, task=trace.task, views=trace.views
    )
    scored = trace.scored_frames  # the query moves only at scored frames (every `stride`-th)
    stacked = np.concatenate([trace.queries[view] for view in trace.views])
    placed = memory_map.project(stacked).reshape(len(trace.views), len(scored), 2)
    for position, view in enumerate(trace.views):
        rec.send_columns(
            paths.umap_query(view),
            indexes=time_columns(scored, fps),
            columns=rr.Points2D.columns(positions=placed[position]).partition(
                np.ones(len(scored), dtype=np.int64)
            ),
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


def _markdown_without_images(markdown: str) -> str:
    """Image links become plain references: the viewer must not try to fetch local files."""
    return _MARKDOWN_IMAGE.sub(lambda match: f"`{match[1] or 'image'}: {match[2]}`", markdown)


def _log_detection(
    rec: rr.RecordingStream,
    trace: DetectionTrace,
    paths: DetectorPaths,
    fps: float,
    trajectory: Trajectory | None,
    vlm_answer: VLMAnswer | None = None,
) -> None:
    """The detection event and the failure report at t_det (and the VLM's answer); a summary at frame 0."""
    t_det, view = trace.t_det, trace.detected_view
    rule = trace.rule
    peak = trace.max_score()
    peak_frame = int(np.argmax(peak))
    summary = (
        f"**{trace.task} · {trace.episode}** — encoder `{trace.encoder}`, rule **{rule.value}** "
        f"({rule.score_name} ≥ {rule.symbol} = {trace.threshold:.3f}), K = {trace.k}, L = {trace.length} frames.\n\n"
    )
    set_frame_time(rec, 0, fps)
    if t_det is None or view is None:
        rec.log(
            paths.report,
            rr.TextDocument(
                summary + f"**No failure detected.** The highest {rule.score_name} over all views is "
                f"{float(peak[peak_frame]):.3f} at frame {peak_frame}, below {rule.symbol}.",
                media_type=rr.MediaType.MARKDOWN,
            ),
        )
        return
    rec.log(
        paths.report,
        rr.TextDocument(
            summary + f"No failure yet: the {rule.value} rule fires at frame **{t_det}** (view {view}).",
            media_type=rr.MediaType.MARKDOWN,
        ),
    )
    report = report_for(trace, trajectory)
    assert report is not None  # t_det is set
    neighbors = trace.neighbors(view, t_det)
    set_frame_time(rec, t_det, fps)
    fired = (
        f"{rule.score_name} = {float(trace.scores[view][t_det]):.3f} ≥ {rule.symbol} = {trace.threshold:.3f}"
    )
    success = trace.nearest_success(view, t_det)
    contrast_line = ""
    if success is not None:
        contrast_line = (
            f"Contrast: S⁻ = {neighbors[0].similarity:.3f} (nearest failure end) − S⁺ = {success.similarity:.3f} "
            f"(nearest success frame: {success.run.episode}, frame {success.frame}) = "
            f"C = {neighbors[0].similarity - success.similarity:.3f}.\n\n"
        )
    log_alarm(
        rec,
        paths,
        report=report,
        top=neighbors[0],
        rule=rule,
        fired=fired,
        summary=summary
        + f"**Fired by the {rule.value} rule** at frame {t_det}, view {view}: {fired}.\n\n"
        + contrast_line,
        vlm_answer=vlm_answer,
    )


def log_alarm(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    *,
    report: FailureReport,
    top: Neighbor,
    rule: ScoreRule,
    fired: str,
    summary: str,
    vlm_answer: VLMAnswer | None = None,
) -> None:
    """At the detection instant (the current time): the event line and the failure report document.

    `fired` says on what score `rule` fired (e.g. "S⁻_t = 0.970 ≥ δ = 0.950")."""
    rec.log(
        paths.event,
        rr.TextLog(
            f"FAILURE at frame {report.t_det} in view {report.view} ({rule.value} rule): {fired}; "
            f"nearest memory entry {top.entry.task}/{top.entry.episode} [{top.entry.view}] "
            f"{top.entry.symbol}: {top.entry.description}",
            level=rr.TextLogLevel.WARN,
        ),
    )
    rec.log(
        paths.report,
        rr.TextDocument(
            summary
            + (vlm_answer.to_markdown() + "\n\n" if vlm_answer is not None else "")
            + _markdown_without_images(report.to_markdown()),
            media_type=rr.MediaType.MARKDOWN,
        ),
    )
