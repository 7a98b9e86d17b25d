"""Replayed trajectories as `.rrd` recordings (docs/recording.md, "The recording layout"): one file per trajectory, blueprint inside."""

from __future__ import annotations

import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.cameras import log_camera_views
from rfr_viz.panels.contrast import log_nearest_successes
from rfr_viz.panels.map import log_map, map_title, trace_map_grid
from rfr_viz.panels.neighbors import Cell, NeighborImages, log_neighbors
from rfr_viz.panels.report import log_detection
from rfr_viz.panels.scores import log_scores, threshold_properties, time_columns
from rfr_viz.panels.signals import log_signals, recorded_signals
from rfr_viz.panels.umap import MemoryMap, fit_map
from rfr_viz.paths import APPLICATION_ID, DEFAULT_FPS, IN_MEMORY, PROPERTIES, REPLAY, DetectorPaths
from rfr_viz.recordings.blueprint import ScorePlots, compare_blueprint, replay_blueprint
from robofailring.atomic import atomic_path
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.signals import SignalValues
from robofailring.detection.detector import DetectionTrace
from robofailring.explain.report import report_for
from robofailring.explain.vlm import VLMAnswer
from robofailring.extras import needs_extra
from robofailring.memory.image_roots import ImageRoots

with needs_extra("viz"):
    import rerun as rr
    import rerun.blueprint as rrb

BATCHING: Final[rr.ChunkBatcherConfig] = rr.ChunkBatcherConfig(
    flush_tick=60.0, flush_num_bytes=4 * 1024 * 1024
)


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
            fps=float(fps or trajectory.frame_rate or DEFAULT_FPS),
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

    `camera_codec` stores the cameras as JPEGs, AV1 or H.264 video, or `auto` (by size; rfr_viz.panels.camera_video).
    `memory_map` is the memory's cached map (`rfr_viz.memory_map(memory, directory=...)`); without
    one it is fitted here, uncached. `fps` drives the "time" timeline (default: the data's, else 10).
    """
    info = RecordingInfo.of(trajectory, fps=fps)
    mapped = memory_map if memory_map is not None else fit_map(trace.memory)
    images = NeighborImages(trace.memory.image_roots)
    cell = images.cell(trace)
    signals, unread = recorded_signals(trajectory, trace.length)
    blueprint = replay_blueprint(
        views=trace.views,
        map_title=map_title(mapped),
        map_grid=trace_map_grid(trace, mapped),
        cell=cell,
        k=trace.k,
        fps=info.fps,
        focus=focus_frame,
        plots=score_plots(trace),
        signals=list(signals),
    )
    with open_recording(out, blueprint, recording_id=recording_id) as rec:
        rec.send_recording_name(f"{info.task}/{info.episode}")
        rec.send_property(
            PROPERTIES,
            rr.AnyValues(
                **_trajectory_properties(info, trace.length),
                **_detector_properties(trace, mapped),
                focus_frame=focus_frame
                if focus_frame is not None
                else -1,  # -1: none (see rfr_viz.viewer.control)
                **_report_properties(trace, trajectory, vlm_answer),
                **signal_properties(signals, unread),
            ),
        )
        log_cameras(rec, trajectory, views=trace.views, length=trace.length, fps=info.fps, codec=camera_codec)
        log_signals(rec, signals, fps=info.fps)
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
    `/<slug>/…`; each encoder has score plots of its own (S_t and δ, C_t and γ, State_t).
    """
    if not traces:
        raise ValueError("compare_recording needs at least one trace")
    info = RecordingInfo.of(trajectory, fps=fps)
    slugs = list(traces)
    maps = {slug: (memory_maps or {}).get(slug) or fit_map(trace.memory) for slug, trace in traces.items()}
    images = NeighborImages(ImageRoots().joined(*(trace.memory.image_roots for trace in traces.values())))
    cells = {slug: images.cell(trace) for slug, trace in traces.items()}
    views = list(dict.fromkeys(view for trace in traces.values() for view in trace.views))
    length = max(trace.length for trace in traces.values())
    signals, unread = recorded_signals(trajectory, length)
    blueprint = compare_blueprint(
        views=views,
        encoders=slugs,
        map_titles=[map_title(maps[slug]) for slug in slugs],
        map_grids=[trace_map_grid(traces[slug], maps[slug]) for slug in slugs],
        cells=[cells[slug] for slug in slugs],
        plots=[score_plots(traces[slug]) for slug in slugs],
        fps=info.fps,
        signals=list(signals),
    )
    with open_recording(out, blueprint, recording_id=recording_id) as rec:
        rec.send_recording_name(f"{info.task}/{info.episode} ({' vs '.join(slugs)})")
        rec.send_property(
            PROPERTIES,
            rr.AnyValues(
                **_trajectory_properties(info, length),
                encoder=", ".join(trace.encoder for trace in traces.values()),
                encoders=", ".join(slugs),
                **signal_properties(signals, unread),
            ),
        )
        log_cameras(rec, trajectory, views=views, length=length, fps=info.fps, codec=camera_codec)
        log_signals(rec, signals, fps=info.fps)
        for slug, trace in traces.items():
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
            )
    return Path(out)


def score_plots(trace: DetectionTrace) -> ScorePlots:
    """What a trace's score plots show (`ScorePlots.of`)."""
    return ScorePlots.of(
        judging=trace.rule,
        thresholds=trace.thresholds,
        failures=trace.has_failures,
        successes=bool(trace.success_similarity),
        bands=trace.bands,
        signals=trace.signals is not None,
    )


@contextmanager
def open_recording(
    out: Path, blueprint: rrb.Blueprint, *, recording_id: str | None
) -> Iterator[rr.RecordingStream]:
    """A recording saved to a temporary file that becomes `out` only if the block succeeds."""
    with atomic_path(Path(out), suffix=".rrd", claim=True) as tmp:
        rec = rr.RecordingStream(
            APPLICATION_ID, recording_id=recording_id or str(uuid.uuid4()), batcher_config=BATCHING
        )
        rec.set_log_time_enabled(False)  # a replay has its own timelines; wall-clock time adds nothing
        with rec:  # leaving the block flushes and closes the file sink, also on error
            rec.save(tmp, default_blueprint=blueprint)
            yield rec


def signal_properties(signals: Mapping[str, SignalValues], unread: Sequence[Skipped]) -> dict[str, Any]:
    """The signals recorded (`name (kind, D)`) and those that could not be, with the reason."""
    return {
        "signals": ", ".join(f"{name} ({s.kind.value}, {len(s.dims)})" for name, s in signals.items()),
        "signals_not_read": "; ".join(skipped.reason for skipped in unread),
    }


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
        "score": trace.rule.name,
        "threshold": float(trace.threshold),
        **threshold_properties(trace),
        "failure_entries": trace.memory.task_size(trace.task),
        "success_entries": len(trace.memory.successes) if trace.memory.successes is not None else 0,
        "k": trace.k,
        "t_det": trace.t_det if trace.t_det is not None else -1,  # -1: the detector never fired
        "detected_view": trace.detected_view or "",
        "views": ", ".join(trace.views),
        "skipped_views": ", ".join(trace.skipped_views),
        "unscored_frames": ", ".join(f"{view}: {count}" for view, count in trace.truncated_views.items()),
        "stride": trace.stride,  # frames 0, stride, 2·stride, … were scored; every camera frame is kept
        "memory_entries": len(trace.memory),
        "failure_frames": trace.memory.manifest.failure_mode,  # `end` (the paper's memory) or `dense`
        "pairing": trace.memory.pairing,  # `concat` (the paper's) or `change`
        IN_MEMORY: trace.in_memory,  # scored against a memory holding this trajectory (no --leave-one-out)
        "map": memory_map.method,
        "map_note": memory_map.note,
    }


def log_cameras(
    rec: rr.RecordingStream,
    trajectory: Trajectory,
    *,
    views: Sequence[str],
    length: int,
    fps: float,
    codec: CameraCodec | str = CameraCodec.JPEG,
) -> None:
    """`/camera/<view>`: JPEG per frame, or AV1/H.264 video (rfr_viz.panels.camera_video), never raw pixels."""
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
    vlm_answer: VLMAnswer | None = None,
) -> None:
    """Everything that depends on the detector: scores, δ, state, map, neighbours, event and report."""
    images = images or NeighborImages(trace.memory.image_roots)
    log_scores(rec, trace, paths, fps, label=label)
    log_nearest_successes(rec, trace, paths, fps=fps)
    log_map(rec, trace, paths, memory_map, fps)
    log_neighbors(rec, trace, paths, fps=fps, images=images, cell=cell or images.cell(trace))
    log_detection(rec, trace, paths, fps, trajectory, vlm_answer)
