"""Rerun recordings of replayed trajectories (all Rerun code of the project lives here).

The closed-loop simulator run is recorded by `run_closed_loop` (imported on first use: it loads pybullet).
`LiveRecording` is the step API's sink that streams a live session to a viewer (`rfr_viz.recordings.live`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from rfr_viz import _moved as _moved  # old module paths, deprecated (one release)
from rfr_viz.jobs.replay import CompareConfig, ReplayConfig, ReplayResult, compare, replay
from rfr_viz.jobs.review import ReviewConfig, review
from rfr_viz.panels.umap import MemoryMap, fit_map, memory_map
from rfr_viz.paths import APPLICATION_ID, DetectorPaths
from rfr_viz.recordings.blueprint import compare_blueprint, replay_blueprint
from rfr_viz.recordings.evaluation import record_evaluation
from rfr_viz.recordings.live import LiveRecording, LiveTarget
from rfr_viz.recordings.replay import compare_recording, record_replay
from rfr_viz.viewer.control import Screenshot, ViewerUnavailable, open_command, render_screenshot

if TYPE_CHECKING:
    from rfr_viz.recordings.closed_loop import ClosedLoopResult, run_closed_loop

_LAZY = {  # name -> module: the closed-loop recording runs the simulator, so it is imported on first use
    "ClosedLoopResult": "rfr_viz.recordings.closed_loop",
    "run_closed_loop": "rfr_viz.recordings.closed_loop",
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f"module 'rfr_viz' has no attribute {name!r}")
    return getattr(importlib.import_module(_LAZY[name]), name)


__all__ = [
    "APPLICATION_ID",
    "ClosedLoopResult",
    "CompareConfig",
    "DetectorPaths",
    "LiveRecording",
    "LiveTarget",
    "MemoryMap",
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
    "open_command",
    "record_evaluation",
    "record_replay",
    "render_screenshot",
    "replay",
    "replay_blueprint",
    "review",
    "run_closed_loop",
]
