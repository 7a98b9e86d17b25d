"""Rerun recordings of replayed trajectories (all Rerun code of the project lives here).

Every name is imported on first use: `import rfr_viz` (and the `robofailring` command it holds) loads
no Rerun, so the core install runs without the `viz` extra, and a name that needs it says so
(`robofailring.errors.MissingExtraError`). The closed-loop simulator run is recorded by
`run_closed_loop` (it also loads pybullet). `LiveRecording` is the step API's sink that streams a live
session to a viewer (`rfr_viz.recordings.live`). In a notebook, `show(path or trace)` displays a recording
inline with its own blueprint (`rfr_viz.recordings.notebook`, the `notebook` extra).
"""

from __future__ import annotations

import importlib

TYPE_CHECKING = (
    False  # not typing's: `typing` takes milliseconds to load, before the command can catch a Ctrl-C
)

if TYPE_CHECKING:
    from rfr_viz.jobs.compare import CompareConfig, compare
    from rfr_viz.jobs.recorded import Recordings
    from rfr_viz.jobs.replay import ReplayConfig, ReplayResult, replay
    from rfr_viz.jobs.review import ReviewConfig, review
    from rfr_viz.panels.umap import MemoryMap, fit_map, memory_map
    from rfr_viz.paths import APPLICATION_ID, DetectorPaths
    from rfr_viz.recordings.blueprint import compare_blueprint, replay_blueprint
    from rfr_viz.recordings.closed_loop import ClosedLoopResult, run_closed_loop
    from rfr_viz.recordings.evaluation import record_evaluation
    from rfr_viz.recordings.live import LiveRecording
    from rfr_viz.recordings.live_target import LiveTarget
    from rfr_viz.recordings.monitor import MonitorRecorder, monitor_recorder
    from rfr_viz.recordings.notebook import InlineRecording, show
    from rfr_viz.recordings.replay import compare_recording, record_replay
    from rfr_viz.viewer.binary import ViewerUnavailable
    from rfr_viz.viewer.control import Screenshot, open_command, render_screenshot

_LAZY = {  # name -> the module it is imported from on first use
    "APPLICATION_ID": "rfr_viz.paths",
    "ClosedLoopResult": "rfr_viz.recordings.closed_loop",
    "CompareConfig": "rfr_viz.jobs.compare",
    "DetectorPaths": "rfr_viz.paths",
    "InlineRecording": "rfr_viz.recordings.notebook",
    "LiveRecording": "rfr_viz.recordings.live",
    "LiveTarget": "rfr_viz.recordings.live_target",
    "MemoryMap": "rfr_viz.panels.umap",
    "MonitorRecorder": "rfr_viz.recordings.monitor",
    "Recordings": "rfr_viz.jobs.recorded",
    "ReplayConfig": "rfr_viz.jobs.replay",
    "ReplayResult": "rfr_viz.jobs.replay",
    "ReviewConfig": "rfr_viz.jobs.review",
    "Screenshot": "rfr_viz.viewer.control",
    "ViewerUnavailable": "rfr_viz.viewer.binary",
    "compare": "rfr_viz.jobs.compare",
    "compare_blueprint": "rfr_viz.recordings.blueprint",
    "compare_recording": "rfr_viz.recordings.replay",
    "fit_map": "rfr_viz.panels.umap",
    "memory_map": "rfr_viz.panels.umap",
    "monitor_recorder": "rfr_viz.recordings.monitor",
    "open_command": "rfr_viz.viewer.control",
    "record_evaluation": "rfr_viz.recordings.evaluation",
    "record_replay": "rfr_viz.recordings.replay",
    "render_screenshot": "rfr_viz.viewer.control",
    "replay": "rfr_viz.jobs.replay",
    "replay_blueprint": "rfr_viz.recordings.blueprint",
    "review": "rfr_viz.jobs.review",
    "run_closed_loop": "rfr_viz.recordings.closed_loop",
    "show": "rfr_viz.recordings.notebook",
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f"module 'rfr_viz' has no attribute {name!r}")
    return getattr(importlib.import_module(_LAZY[name]), name)


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])


__all__ = [  # every name of _LAZY
    "APPLICATION_ID",
    "ClosedLoopResult",
    "CompareConfig",
    "DetectorPaths",
    "InlineRecording",
    "LiveRecording",
    "LiveTarget",
    "MemoryMap",
    "MonitorRecorder",
    "Recordings",
    "ReplayConfig",
    "ReplayResult",
    "ReviewConfig",
    "Screenshot",
    "ViewerUnavailable",
    "compare",
    "compare_blueprint",
    "compare_recording",
    "fit_map",
    "memory_map",
    "monitor_recorder",
    "open_command",
    "record_evaluation",
    "record_replay",
    "render_screenshot",
    "replay",
    "replay_blueprint",
    "review",
    "run_closed_loop",
    "show",
]
