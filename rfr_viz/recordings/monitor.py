"""The rollout monitor's live recordings (`robofailring.monitor`, docs/rollouts.md): one `.rrd` per episode.

`monitor_recorder(folder)` is what a user passes as `RolloutMonitor(..., recorder=…)`: at each episode's reset
the monitor asks it for a step sink, a `LiveRecording` saved as `<folder>/<episode>.rrd` (and streamed to a
viewer with `connect` or `spawn`), closed and saved whole when the episode ends.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from rfr_viz.codecs import CameraCodec
from rfr_viz.paths import DEFAULT_FPS
from rfr_viz.recordings.live import LiveRecording
from rfr_viz.recordings.live_target import LiveTarget
from robofailring.detection.detector import FailureDetector


@dataclass(frozen=True)
class MonitorRecorder:
    """An `EpisodeRecorder` (`robofailring.monitor.tracker`): a live recording per episode."""

    folder: Path
    fps: float = DEFAULT_FPS
    connect: str | None = None  # also stream each episode to a running viewer at this URL
    spawn: bool = False  # also stream to a viewer started on the default port
    camera_codec: CameraCodec | str = CameraCodec.JPEG

    @contextmanager
    def episode(
        self, detector: FailureDetector, *, task: str, views: Sequence[str], name: str
    ) -> Iterator[LiveRecording]:
        target = LiveTarget(connect=self.connect, spawn=self.spawn, save=Path(self.folder) / f"{name}.rrd")
        with LiveRecording.open(
            detector,
            task,
            views=views,
            target=target,
            fps=self.fps,
            name=name,
            camera_codec=self.camera_codec,
        ) as live:
            yield live


def monitor_recorder(
    folder: str | Path,
    *,
    fps: float = DEFAULT_FPS,
    connect: str | None = None,
    spawn: bool = False,
    camera_codec: CameraCodec | str = CameraCodec.JPEG,
) -> MonitorRecorder:
    """The monitor's live `.rrd` per episode under `folder` (`recorder=` of `RolloutMonitor`)."""
    return MonitorRecorder(Path(folder), fps=fps, connect=connect, spawn=spawn, camera_codec=camera_codec)
