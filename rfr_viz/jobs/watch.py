"""The watch job: one episode fed to the detector's step API frame by frame, streamed live."""

from __future__ import annotations

import logging
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from rfr_viz.codecs import CameraCodec
from rfr_viz.jobs.recorded import check_fps
from rfr_viz.jobs.replay import check_speed, load_detector
from rfr_viz.paths import DEFAULT_FPS
from rfr_viz.recordings.live import LiveRecording
from rfr_viz.recordings.live_target import LiveTarget
from rfr_viz.viewer.rrd import check_recording_file
from robofailring.atomic import output_lock
from robofailring.data.model import Skipped
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.detection.scored import blank_skips
from robofailring.errors import BlindCameraWarning, DataError
from robofailring.outputs import check_not_input, check_writable


@dataclass(frozen=True)
class WatchConfig:
    data: DataSelection  # one episode folder, fed frame by frame, how it is read (its task, its views)
    detector: DetectorConfig  # the memory (its cached map is shown) and how its detector judges
    target: LiveTarget  # viewer URL, spawn, and/or a file
    speed: float = 1.0  # 1: the data's frame rate; 2: twice as fast; 0: as fast as the detector goes
    fps: float | None = None  # default: the data's, else 10
    camera_codec: CameraCodec = CameraCodec.JPEG  # jpeg, av1 or h264 (auto: jpeg, live)


@dataclass(frozen=True)
class WatchResult:
    steps: int  # L, frames fed
    fired_at: int | None  # the first alarm (t_det)
    detected_view: str | None
    saved: Path | None
    lost: str | None = None  # why the viewer did not get the whole stream, if it did not
    blind: list[Skipped] = field(default_factory=list)  # views blank to the encoder, with their frames

    def to_text(self) -> str:
        """What `robofailring watch` says at the end: the steps, the alarm (or none), the saved file. A
        run whose cameras were blind for some frames is not said to have had no failure."""
        if self.fired_at is None and self.blind:
            text = (
                f"{self.steps} steps watched: no alarm, but {len(self.blind)} view(s) blind for some frames"
            )
        elif self.fired_at is None:
            text = f"{self.steps} steps watched: no failure detected"
        else:
            text = (
                f"{self.steps} steps watched: FAILURE at frame {self.fired_at} in view {self.detected_view}"
            )
        return text if self.saved is None else f"{text}\nsaved the stream to {self.saved}"


def watch(config: WatchConfig) -> WatchResult:
    """Feed one episode through `detector.session(...).step` frame by frame, streaming every step; a
    saved file's lock is held from its checks to its last step (a second writer of it stops before work)."""
    check_speed(config.speed)
    check_fps(config.fps)
    if config.target.save is None:
        return _watch(config)
    save = Path(config.target.save)  # before any work: never over an input, never over a non-recording
    check_not_input(
        save,
        [config.data.root, config.detector.memory, config.detector.data_root],
        replaces=False,
        flag="--save",
    )
    check_writable(save.absolute().parent)
    with output_lock(save):
        check_recording_file(save)
        return _watch(config)


def _watch(config: WatchConfig) -> WatchResult:
    loaded = load_detector(config.detector, config.data.root)
    trajectory = config.data.load_trajectory()
    used = {view: frames for view, frames in trajectory.views.items() if len(frames) >= 2}
    if not used:
        raise DataError(f"episode {config.data.root} has no view with at least 2 frames")
    length = min(len(frames) for frames in used.values())  # views in step, as a replay scores them
    fps = float(config.fps or trajectory.frame_rate or DEFAULT_FPS)
    signals, _ = trajectory.read_signals()  # one that cannot be read is not sent (replay lists why)
    memory_signals = loaded.detector.memory.signals
    task_signals = memory_signals.task(trajectory.task) if memory_signals is not None else None
    lacking = [n for n in (task_signals.layout.names if task_signals else []) if n not in signals]
    if lacking:
        logging.getLogger("robofailring").warning(
            "warning: %s lacks signal %r of the memory: its cameras judge alone", trajectory.key, lacking[0]
        )
    with LiveRecording.open(
        loaded.detector,
        trajectory.task,
        views=list(used),
        target=config.target,
        fps=fps,
        memory_map=loaded.map,
        name=f"{trajectory.task}/{trajectory.episode}",
        camera_codec=config.camera_codec,
        signals=list(signals),
        source=trajectory.source,
    ) as live:
        session = loaded.detector.session(trajectory.task, sink=live)
        started = time.monotonic()
        with warnings.catch_warnings():  # the result lists the blind frames, once
            warnings.simplefilter("ignore", BlindCameraWarning)
            for t in range(length):
                if config.speed > 0:
                    time.sleep(max(0.0, started + t / (fps * config.speed) - time.monotonic()))
                now = {name: found.values[t] for name, found in signals.items() if t < len(found.values)}
                live.log_signals(t, now)
                session.step(
                    {view: frames[t] for view, frames in used.items()}, signals=None if lacking else now
                )
    return WatchResult(
        steps=length,
        fired_at=live.fired_at,
        detected_view=live.report.view if live.report is not None else None,
        saved=Path(config.target.save) if config.target.save is not None else None,
        lost=live.lost,
        blind=blank_skips(trajectory, session.blind_steps, length),
    )
