"""Watching a robot live: each step of a detector session streamed to a Rerun viewer, and/or saved.

`LiveRecording` is the library's `StepSink` for Rerun: pass it as `detector.session(task, sink=live)`
and every `session.step(...)` is logged at once with the entity paths of a replay (rfr_viz.paths):
`/camera/<view>`, `/score/<view>/<rule>`, `/score/threshold/<rule>` (and `/score/threshold/<rule>/<view>` for a
view judged by a band of its own), `/detection/state`, the moving map query, the neighbours when they change,
and the detection event and failure report at the first alarm.
`watch` feeds a recorded episode through the same loop, frame by frame, as a robot would.
"""

from __future__ import annotations

import logging
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any, Final

import numpy as np

from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.contrast import log_nearest_success
from rfr_viz.panels.images import ReferenceJpegs
from rfr_viz.panels.live_camera import LiveCameras
from rfr_viz.panels.map import MapGrid, class_id, log_memory_map, map_grid, map_title
from rfr_viz.panels.neighbors import (
    DEFAULT_CELL,
    Cell,
    NeighborImages,
    log_neighbor_entry,
    log_neighbor_layout,
    log_no_failures,
)
from rfr_viz.panels.report import log_alarm
from rfr_viz.panels.scores import log_score_styles, set_frame_time, threshold_properties
from rfr_viz.panels.umap import MemoryMap
from rfr_viz.paths import APPLICATION_ID, DEFAULT_FPS, PROPERTIES, REPLAY, signal
from rfr_viz.recordings.blueprint import ScorePlots, replay_blueprint
from rfr_viz.recordings.live_target import LiveTarget
from robofailring.data.model import Frame
from robofailring.detection.detector import FailureDetector
from robofailring.detection.session import DetectorSession, StepResult
from robofailring.errors import Terminated
from robofailring.explain.report import FailureReport, signals_sentence
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr

_log = logging.getLogger("robofailring")
FLUSH_TIMEOUT_S: Final[float] = 10.0  # at the end, wait this long at most for a viewer to take the rest


def _score_plots(detector: FailureDetector, task: str) -> ScorePlots:
    """The live session's score plots, as a replay of its task would have them."""
    return ScorePlots.of(
        judging=detector.rule_for(task),
        thresholds=detector.thresholds,
        failures=detector.memory.has_failures(task),
        successes=detector.memory.successes is not None,
        bands={
            name: band.for_task(task) for name, band in detector.bands.items()
        },  # the task's, as it judges
        signals=detector.memory.signals is not None and detector.memory.signals.task(task) is not None,
    )


class LiveRecording:
    """A `StepSink` that logs every step of a session to a Rerun recording stream as it happens."""

    def __init__(
        self,
        rec: rr.RecordingStream,
        detector: FailureDetector,
        *,
        task: str,
        views: Sequence[str],
        fps: float = DEFAULT_FPS,
        memory_map: MemoryMap | None = None,
        name: str = "live",
        cell: Cell = DEFAULT_CELL,
        camera_codec: CameraCodec | str = CameraCodec.JPEG,
        source: Path | None = None,
    ) -> None:
        self.rec = rec
        self.source = source  # the run's folder or file, when it is replayed from one (the report's root)
        self.camera_codec = camera_codec  # jpeg, av1 or h264 (auto: jpeg); used from the first step
        self.cell = cell
        self.detector = detector
        self.task = task
        self.views = list(views)
        self.fps = fps
        self.memory_map = memory_map
        self.name = name
        self.images = NeighborImages(detector.memory.image_roots)
        self.steps = 0
        self.fired_at: int | None = None
        self.report: FailureReport | None = None
        self.lost: str | None = None  # why the viewer did not get everything, if it did not
        self._shown: dict[tuple[str, int], int] = {}  # (view, rank) -> memory entry index on screen
        self._success_shown: dict[str, int] = {}  # view -> success-memory row on screen (-1: none)
        self._success_images = ReferenceJpegs(detector.memory.image_roots)

    @classmethod
    @contextmanager
    def open(
        cls,
        detector: FailureDetector,
        task: str,
        *,
        views: Sequence[str],
        target: LiveTarget,
        fps: float = DEFAULT_FPS,
        memory_map: MemoryMap | None = None,
        name: str | None = None,
        camera_codec: CameraCodec | str = CameraCodec.JPEG,
        signals: Sequence[str] = (),
        source: Path | None = None,
    ) -> Iterator[LiveRecording]:
        """A live recording streamed to `target`, with the replay layout as its blueprint; cameras
        stored as `camera_codec` (rfr_viz.panels.live_camera: `auto` means JPEG live); the robot's
        `signals` (logged with `log_signals`) a tab each.

        On leaving the block the recording's properties (t_det, the report, …) are sent, the stream
        is flushed, and a saved file appears at `target.save` (not on error); while it is written, the
        file's `output_lock` is held and its temporary file is left alone by any other job's cleaning.
        """
        target.check()
        entries = detector.memory.entries
        cell = _cell(entries[0].start if entries else "", NeighborImages(detector.memory.image_roots))
        blueprint = replay_blueprint(
            views=views,
            map_title=map_title(memory_map) if memory_map is not None else "memory map (not given)",
            map_grid=(
                map_grid(memory_map, [class_id(entry.symbol, entry.vocabulary) for entry in entries])
                if memory_map is not None
                else MapGrid(views=0, legend_entries=0)
            ),
            cell=cell,
            k=detector.k,
            plots=_score_plots(detector, task),
            fps=fps,
            signals=signals,
        )
        with ExitStack() as stack:
            rec = rr.RecordingStream(APPLICATION_ID, recording_id=str(uuid.uuid4()))
            url = target.send(rec, stack, blueprint)
            live = cls(
                rec,
                detector,
                task=task,
                views=views,
                fps=fps,
                memory_map=memory_map,
                name=name or task,
                cell=cell,
                camera_codec=camera_codec,
                source=source,
            )
            live._start()
            stopped: BaseException | None = None
            try:
                try:
                    yield live
                except (KeyboardInterrupt, Terminated) as error:  # stopped: keep what was recorded, whole
                    stopped = error
                live._finish()
            finally:
                try:
                    rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
                except RuntimeError as error:  # the viewer went away; a file sink is flushed all the same
                    live.lost = f"the viewer at {url} did not take the whole stream ({error})"
                rec.disconnect()  # closes the file before atomic_path moves it into place
        if stopped is not None:
            if target.save is not None:
                _log.warning(
                    "warning: stopped after %d step(s); what was recorded is saved, complete, in %s",
                    live.steps,
                    target.save,
                )
            raise stopped

    def _start(self) -> None:
        paths = REPLAY
        self.rec.send_recording_name(f"{self.name} (live)")
        self.cameras = LiveCameras(
            self.rec, self.views, codec=self.camera_codec, fps=self.fps, name=self.name
        )
        failures = self.detector.memory.has_failures(self.task)
        self.plots = _score_plots(self.detector, self.task)
        log_score_styles(
            self.rec,
            paths,
            views=self.plots.scored(self.views),
            rules=self.plots.rules,
            judging=self.detector.rule_for(self.task),
            thresholds=self.plots.thresholds,
            bands=self.plots.bands,
            successes=self.plots.successes,
        )
        if not failures:
            for view in self.views:
                log_no_failures(self.rec, paths, view, task=self.task)
        if self.memory_map is not None:
            log_memory_map(
                self.rec,
                paths,
                entries=self.detector.memory.entries,
                memory_map=self.memory_map,
                task=self.task,
                views=self.views,
            )
        for view in self.views:
            log_neighbor_layout(self.rec, paths, view, k=self.detector.k, cell=self.cell)
        set_frame_time(self.rec, 0, self.fps)
        self.rec.log(
            paths.report,
            rr.TextDocument(
                self._summary() + "Watching live: no failure yet.", media_type=rr.MediaType.MARKDOWN
            ),
        )

    def _summary(self) -> str:
        rule = self.detector.rule_for(self.task)
        return (
            f"**{self.name}** — encoder `{self.detector.encoder.identity}`, rule **{rule.name}** "
            f"({rule.score_name} ≥ {rule.symbol} = {self.detector.threshold_of(rule):.3f}), K = {self.detector.k}, live.\n\n"
        )

    def on_step(
        self, session: DetectorSession, frames: Mapping[str, np.ndarray | Frame], result: StepResult
    ) -> None:
        """Log one step at frame `result.t`: cameras, S_t, δ, State_t, map query, neighbours, alarm."""
        rec, paths, t = self.rec, REPLAY, result.t
        set_frame_time(rec, t, self.fps)
        for view, frame in frames.items():
            self.cameras.log(view, frame, t)
        for rule in self.plots.rules:  # each shown rule's score where it was scored, and its threshold
            for view, score in result.rule_scores[rule.name].items():
                if np.isfinite(score):
                    rec.log(paths.score(view, rule.name), rr.Scalars(score))
            rec.log(paths.threshold(rule.name), rr.Scalars(result.thresholds[rule.name]))
            band = self.plots.bands.get(rule.name)
            for view, line in result.view_thresholds.get(rule.name, {}).items():
                if band is not None and view in band.views:  # judged by a band of its own: its own line
                    rec.log(paths.view_threshold(rule.name, view), rr.Scalars(line))
        rec.log(paths.state, rr.Scalars(float(result.alarm)))
        if self.plots.successes:
            for view, similarity in result.success_similarity.items():  # each view judged, the signals too
                if np.isfinite(similarity):
                    rec.log(paths.success_score(view), rr.Scalars(similarity))
            for view, match in result.nearest_success.items():
                changed = self._success_shown.get(view, -1) != (match.index if match else -1)
                self._success_shown[view] = match.index if match else -1
                log_nearest_success(rec, paths, view, match, t=t, images=self._success_images, image=changed)
        if self.memory_map is not None:
            for view, query in result.queries.items():
                placed = self.memory_map.project(view, self.task, query)
                if placed is not None:
                    rec.log(paths.umap_query(view), rr.Points2D.from_fields(positions=placed[:1]))
        first_alarm = result.alarm and self.fired_at is None
        self._log_neighbors(
            result, every=first_alarm
        )  # at the alarm, as a replay: the similarities that fired
        if first_alarm:
            self._alarm(session, frames, result)
        self.steps = max(self.steps, t + 1)

    def log_signals(self, t: int, signals: Mapping[str, np.ndarray]) -> None:
        """The robot's signals at step `t` ({name: (D,) values}) at `/signals/<name>`, as a replay has them."""
        set_frame_time(self.rec, t, self.fps)
        for name, values in signals.items():
            self.rec.log(signal(name), rr.Scalars(np.asarray(values, np.float64).reshape(-1)))

    def _log_neighbors(self, result: StepResult, *, every: bool) -> None:
        """Each view's K neighbours that changed since the last step (`every`: all of them)."""
        for view, found in result.neighbors.items():
            for rank, neighbor in enumerate(found):
                if every or self._shown.get((view, rank)) != neighbor.index:
                    self._shown[(view, rank)] = neighbor.index
                    log_neighbor_entry(
                        self.rec,
                        REPLAY,
                        view,
                        rank,
                        neighbor.entry,
                        similarity=neighbor.similarity,
                        t=result.t,
                        images=self.images,
                        cell=self.cell,
                    )

    def _alarm(
        self, session: DetectorSession, frames: Mapping[str, np.ndarray | Frame], result: StepResult
    ) -> None:
        """The event and the report at the first alarm: the camera's neighbours where one explains it, the
        robot's signals' nearest runs where they were scored (all there is when they were judged alone)."""
        view, camera = result.detected_view, result.camera_view
        assert view is not None  # an alarm has a firing view
        frame = frames[camera] if camera is not None else None
        neighbors = result.neighbors[camera] if camera is not None else []
        self.fired_at = result.t
        self.report = FailureReport.from_neighbors(
            task=self.task,
            view=view,
            t_det=result.t,
            neighbors=neighbors,
            current_image=frame.reference if isinstance(frame, Frame) and frame.path is not None else None,
            similarity=None if camera == view else result.similarity[view],
            signals=signals_sentence(session.signal_scores, 0),
            roots=self._roots(frame),
        )
        line = result.view_thresholds.get(result.rule.name, {}).get(view, result.threshold)
        fired = f"{result.rule.score_name} = {result.score[view]:.3f} ≥ {result.rule.symbol} = {line:.3f}"
        log_alarm(
            self.rec,
            REPLAY,
            report=self.report,
            top=neighbors[0] if neighbors else None,
            nearest_success=result.nearest_success.get(camera) if camera is not None else None,
            rule=result.rule,
            fired=fired,
            summary=self._summary()
            + (f"Robot signals: {self.report.signals}.\n\n" if self.report.signals is not None else ""),
        )

    def _roots(self, frame: np.ndarray | Frame | None) -> list[str]:
        """Where the report's images may come from: the folders named for the memory's images
        (`FailureMemory.image_roots`), and the run's folder (that of the frame's file when the run came from
        no file)."""
        roots = list(map(str, self.detector.memory.image_roots.folders))
        if self.source is not None:
            source = Path(self.source).resolve()
            roots.append(str(source if source.is_dir() else source.parent))
        elif isinstance(frame, Frame) and frame.path is not None:
            roots.append(str(frame.path.resolve().parent))
        return roots

    def _finish(self) -> None:
        self.cameras.finish()  # the frames a video encoder still held, at their own frames
        rule = self.detector.rule_for(self.task)
        found: dict[str, Any] = {
            "task": self.task,
            "episode": self.name,
            "L": self.steps,
            "fps": float(self.fps),
            "encoder": self.detector.encoder.identity,
            "score": rule.name,
            "threshold": float(self.detector.threshold_of(rule)),
            **threshold_properties(self.detector),
            "k": self.detector.k,
            "t_det": self.fired_at if self.fired_at is not None else -1,  # -1: the detector never fired
            "views": ", ".join(self.views),
            "live": True,
        }
        if self.report is not None:
            found["detected_view"] = self.report.view
            found["report"] = self.report.to_json()
        self.rec.send_property(PROPERTIES, rr.AnyValues(**found))


def _cell(reference: str, images: NeighborImages) -> Cell:
    """The neighbour grid's cell: the size of a memory image, else the default."""
    image = images.get(reference) if reference else None
    return Cell(image.width, image.height) if image is not None else DEFAULT_CELL
