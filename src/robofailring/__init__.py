"""RoboFailRing: retrieval-augmented, language-grounded robot failure detection (library, no Rerun).

The names a robot loop, a notebook and an evaluation script need::

    detector = robofailring.open_detector("memories/aha-b32")
    session = detector.session("pick_cube")
    result = session.step({"front": rgb})   # result.alarm, result.score, result.threshold

Every name but the errors is imported on first use, so `import robofailring` loads no heavy package
(numpy, OpenCV and Faiss come with the first name that needs them; the simulator's names,
`generate_dataset`, `GenerateConfig`, `run_episode` and `SIM_VIEWS`, load pybullet), and the
`robofailring` command reaches its own code before any of them (a Ctrl-C while they load ends as
one during a verb: `robofailring.cli.exit_codes`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from robofailring.errors import (
    BlindCameraWarning,
    DataError,
    EncoderError,
    EncoderMismatchError,
    MemoryFormatError,
    RoboFailRingError,
    RolloutError,
    SettingError,
    SymbolError,
    UnknownTaskError,
)

if TYPE_CHECKING:
    from robofailring.calibration.conformal import smallest_target_fpr
    from robofailring.calibration.job import CalibrateConfig, Calibration, calibrate
    from robofailring.calibration.policy import ThresholdPolicy
    from robofailring.data.grounding import ground, parse_symbol
    from robofailring.data.layouts import Dataset, load_dataset, load_trajectory
    from robofailring.data.model import Frame, Outcome, Trajectory
    from robofailring.data.selection import DataSelection
    from robofailring.detection.config import DetectorConfig, Scoring
    from robofailring.detection.detector import FailureDetector
    from robofailring.detection.loader import open_detector
    from robofailring.detection.rules import PAPER_DELTA, RULES, ScoringRule, rule_named
    from robofailring.detection.session import DetectorSession, StepResult, StepSink
    from robofailring.detection.trace import DetectionTrace
    from robofailring.encoders import CachedEncoder, Encoder, default_cache_dir, load_encoder, open_encoder
    from robofailring.encoders.placement import EncoderPlacement
    from robofailring.evaluation.job import EvaluateConfig, run_evaluation
    from robofailring.explain.report import FailureReport, VLMClient
    from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
    from robofailring.jobs.compare_encoders import CompareEncodersConfig, compare_encoders, comparison_table
    from robofailring.jobs.detect import DetectConfig, detect
    from robofailring.memory.entry import MemoryEntry, Neighbor
    from robofailring.memory.failure import FailureMemory
    from robofailring.memory.recipe import MemoryRecipe
    from robofailring.memory.success import SuccessMemory
    from robofailring.monitor.adapters import (
        LeRobotAdapter,
        ManiSkillAdapter,
        MappingAdapter,
        RobosuiteAdapter,
    )
    from robofailring.monitor.sim_env import SIM_ADAPTER, SimEnv
    from robofailring.monitor.summary import RolloutSummary
    from robofailring.monitor.vector import VectorRolloutMonitor
    from robofailring.monitor.verdict import Verdict
    from robofailring.monitor.wrapper import LegacyEnv, RolloutMonitor
    from robofailring.sim import VIEWS as SIM_VIEWS
    from robofailring.sim import GenerateConfig, generate_dataset, run_episode

__version__ = "0.1.0"

_LAZY = {  # name -> (module, attribute), imported on first use (the simulator's load pybullet)
    "BuildMemoryConfig": ("robofailring.jobs.build_memory", "BuildMemoryConfig"),
    "CachedEncoder": ("robofailring.encoders", "CachedEncoder"),
    "CalibrateConfig": ("robofailring.calibration.job", "CalibrateConfig"),
    "Calibration": ("robofailring.calibration.job", "Calibration"),
    "CompareEncodersConfig": ("robofailring.jobs.compare_encoders", "CompareEncodersConfig"),
    "DataSelection": ("robofailring.data.selection", "DataSelection"),
    "Dataset": ("robofailring.data.layouts", "Dataset"),
    "DetectConfig": ("robofailring.jobs.detect", "DetectConfig"),
    "DetectionTrace": ("robofailring.detection.trace", "DetectionTrace"),
    "DetectorConfig": ("robofailring.detection.config", "DetectorConfig"),
    "DetectorSession": ("robofailring.detection.session", "DetectorSession"),
    "Encoder": ("robofailring.encoders", "Encoder"),
    "EncoderPlacement": ("robofailring.encoders.placement", "EncoderPlacement"),
    "EvaluateConfig": ("robofailring.evaluation.job", "EvaluateConfig"),
    "FailureDetector": ("robofailring.detection.detector", "FailureDetector"),
    "FailureMemory": ("robofailring.memory.failure", "FailureMemory"),
    "FailureReport": ("robofailring.explain.report", "FailureReport"),
    "Frame": ("robofailring.data.model", "Frame"),
    "MemoryEntry": ("robofailring.memory.entry", "MemoryEntry"),
    "MemoryRecipe": ("robofailring.memory.recipe", "MemoryRecipe"),
    "Neighbor": ("robofailring.memory.entry", "Neighbor"),
    "Outcome": ("robofailring.data.model", "Outcome"),
    "PAPER_DELTA": ("robofailring.detection.rules", "PAPER_DELTA"),
    "RULES": ("robofailring.detection.rules", "RULES"),
    "Scoring": ("robofailring.detection.config", "Scoring"),
    "ScoringRule": ("robofailring.detection.rules", "ScoringRule"),
    "StepResult": ("robofailring.detection.session", "StepResult"),
    "StepSink": ("robofailring.detection.session", "StepSink"),
    "SuccessMemory": ("robofailring.memory.success", "SuccessMemory"),
    "ThresholdPolicy": ("robofailring.calibration.policy", "ThresholdPolicy"),
    "Trajectory": ("robofailring.data.model", "Trajectory"),
    "VLMClient": ("robofailring.explain.report", "VLMClient"),
    "build_memory": ("robofailring.jobs.build_memory", "build_memory"),
    "calibrate": ("robofailring.calibration.job", "calibrate"),
    "compare_encoders": ("robofailring.jobs.compare_encoders", "compare_encoders"),
    "comparison_table": ("robofailring.jobs.compare_encoders", "comparison_table"),
    "default_cache_dir": ("robofailring.encoders", "default_cache_dir"),
    "detect": ("robofailring.jobs.detect", "detect"),
    "ground": ("robofailring.data.grounding", "ground"),
    "load_dataset": ("robofailring.data.layouts", "load_dataset"),
    "load_encoder": ("robofailring.encoders", "load_encoder"),
    "load_trajectory": ("robofailring.data.layouts", "load_trajectory"),
    "open_detector": ("robofailring.detection.loader", "open_detector"),
    "open_encoder": ("robofailring.encoders", "open_encoder"),
    "parse_symbol": ("robofailring.data.grounding", "parse_symbol"),
    "rule_named": ("robofailring.detection.rules", "rule_named"),
    "run_evaluation": ("robofailring.evaluation.job", "run_evaluation"),
    "smallest_target_fpr": ("robofailring.calibration.conformal", "smallest_target_fpr"),
    "GenerateConfig": ("robofailring.sim", "GenerateConfig"),
    "generate_dataset": ("robofailring.sim", "generate_dataset"),
    "run_episode": ("robofailring.sim", "run_episode"),
    "SIM_VIEWS": ("robofailring.sim", "VIEWS"),
    # the rollout monitor: the wrappers load gymnasium (the gym extra), SimEnv also pybullet
    "LeRobotAdapter": ("robofailring.monitor.adapters", "LeRobotAdapter"),
    "LegacyEnv": ("robofailring.monitor.wrapper", "LegacyEnv"),
    "ManiSkillAdapter": ("robofailring.monitor.adapters", "ManiSkillAdapter"),
    "MappingAdapter": ("robofailring.monitor.adapters", "MappingAdapter"),
    "RobosuiteAdapter": ("robofailring.monitor.adapters", "RobosuiteAdapter"),
    "RolloutMonitor": ("robofailring.monitor.wrapper", "RolloutMonitor"),
    "RolloutSummary": ("robofailring.monitor.summary", "RolloutSummary"),
    "SimEnv": ("robofailring.monitor.sim_env", "SimEnv"),
    "SIM_ADAPTER": ("robofailring.monitor.sim_env", "SIM_ADAPTER"),
    "VectorRolloutMonitor": ("robofailring.monitor.vector", "VectorRolloutMonitor"),
    "Verdict": ("robofailring.monitor.verdict", "Verdict"),
}


def __getattr__(name: str) -> object:
    if name not in _LAZY:
        raise AttributeError(f"module 'robofailring' has no attribute {name!r}")
    module, attribute = _LAZY[name]
    return getattr(importlib.import_module(module), attribute)


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])


__all__ = [
    "PAPER_DELTA",
    "RULES",
    "SIM_ADAPTER",
    "SIM_VIEWS",
    "BlindCameraWarning",
    "BuildMemoryConfig",
    "CachedEncoder",
    "CalibrateConfig",
    "Calibration",
    "CompareEncodersConfig",
    "DataError",
    "DataSelection",
    "Dataset",
    "DetectConfig",
    "DetectionTrace",
    "DetectorConfig",
    "DetectorSession",
    "Encoder",
    "EncoderError",
    "EncoderMismatchError",
    "EncoderPlacement",
    "EvaluateConfig",
    "FailureDetector",
    "FailureMemory",
    "FailureReport",
    "Frame",
    "GenerateConfig",
    "LeRobotAdapter",
    "LegacyEnv",
    "ManiSkillAdapter",
    "MappingAdapter",
    "MemoryEntry",
    "MemoryFormatError",
    "MemoryRecipe",
    "Neighbor",
    "Outcome",
    "RoboFailRingError",
    "RobosuiteAdapter",
    "RolloutError",
    "RolloutMonitor",
    "RolloutSummary",
    "Scoring",
    "ScoringRule",
    "SettingError",
    "SimEnv",
    "StepResult",
    "StepSink",
    "SuccessMemory",
    "SymbolError",
    "ThresholdPolicy",
    "Trajectory",
    "UnknownTaskError",
    "VLMClient",
    "VectorRolloutMonitor",
    "Verdict",
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
