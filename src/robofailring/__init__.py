"""RoboFailRing: retrieval-augmented, language-grounded robot failure detection (library, no Rerun).

The names a robot loop, a notebook and an evaluation script need::

    detector = robofailring.open_detector("memories/aha-b32")
    session = detector.session("pick_cube")
    result = session.step({"front": rgb})   # result.alarm, result.score, result.threshold

The simulator's names (`generate_dataset`, `GenerateConfig`, `run_episode`, `SIM_VIEWS`) load
pybullet and are imported on first use; `import robofailring` loads no heavy package.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from robofailring.data.grounding import ground, parse_symbol
from robofailring.data.layouts import Dataset, load_dataset, load_trajectory
from robofailring.data.model import Frame, Outcome, Trajectory
from robofailring.detection.conformal import smallest_target_fpr
from robofailring.detection.detector import DetectorSession, FailureDetector, StepSink
from robofailring.detection.loader import open_detector
from robofailring.detection.rules import PAPER_DELTA, RULES, ScoringRule, rule_named
from robofailring.detection.trace import DetectionTrace, StepResult
from robofailring.encoders import CachedEncoder, Encoder, default_cache_dir, load_encoder, open_encoder
from robofailring.errors import (
    DataError,
    EncoderError,
    EncoderMismatchError,
    MemoryFormatError,
    RoboFailRingError,
    SettingError,
    SymbolError,
    UnknownTaskError,
)
from robofailring.evaluation.calibration import CalibrateConfig, Calibration, calibrate
from robofailring.evaluation.comparison import CompareEncodersConfig, compare_encoders, comparison_table
from robofailring.evaluation.run import EvaluateConfig, run_evaluation
from robofailring.explain.report import FailureReport, VLMClient
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.jobs.detect import DetectConfig, detect
from robofailring.memory.entry import MemoryEntry, Neighbor
from robofailring.memory.failure import FailureMemory
from robofailring.memory.success import SuccessMemory

if TYPE_CHECKING:
    from robofailring.sim import VIEWS as SIM_VIEWS
    from robofailring.sim import GenerateConfig, generate_dataset, run_episode

__version__ = "0.1.0"

_LAZY = {  # name -> (module, attribute): the simulator loads pybullet, so it is imported on first use
    "GenerateConfig": ("robofailring.sim", "GenerateConfig"),
    "generate_dataset": ("robofailring.sim", "generate_dataset"),
    "run_episode": ("robofailring.sim", "run_episode"),
    "SIM_VIEWS": ("robofailring.sim", "VIEWS"),
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f"module 'robofailring' has no attribute {name!r}")
    module, attribute = _LAZY[name]
    return getattr(importlib.import_module(module), attribute)


__all__ = [
    "PAPER_DELTA",
    "RULES",
    "SIM_VIEWS",
    "BuildMemoryConfig",
    "CachedEncoder",
    "CalibrateConfig",
    "Calibration",
    "CompareEncodersConfig",
    "DataError",
    "Dataset",
    "DetectConfig",
    "DetectionTrace",
    "DetectorSession",
    "Encoder",
    "EncoderError",
    "EncoderMismatchError",
    "EvaluateConfig",
    "FailureDetector",
    "FailureMemory",
    "FailureReport",
    "Frame",
    "GenerateConfig",
    "MemoryEntry",
    "MemoryFormatError",
    "Neighbor",
    "Outcome",
    "RoboFailRingError",
    "ScoringRule",
    "SettingError",
    "StepResult",
    "StepSink",
    "SuccessMemory",
    "SymbolError",
    "Trajectory",
    "UnknownTaskError",
    "VLMClient",
    "build_memory",
    "calibrate",
    "compare_encoders",
    "comparison_table",
    "default_cache_dir",
    "detect",
    "generate_dataset",
    "ground",
    "load_dataset",
    "load_encoder",
    "load_trajectory",
    "open_detector",
    "open_encoder",
    "parse_symbol",
    "rule_named",
    "run_episode",
    "run_evaluation",
    "smallest_target_fpr",
]
