"""RoboFailRing: retrieval-augmented, language-grounded robot failure detection (library, no Rerun)."""

from __future__ import annotations

from robofailring.data import Dataset, Frame, Outcome, Trajectory, load_dataset, load_trajectory
from robofailring.detector import (
    PAPER_DELTA,
    DetectionTrace,
    DetectorSession,
    FailureDetector,
    StepResult,
    StepSink,
)
from robofailring.encoders import CachedEncoder, Encoder, load_encoder
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
from robofailring.grounding import ground, parse_symbol
from robofailring.memory import FailureMemory, MemoryEntry, Neighbor, pair_vectors
from robofailring.report import FailureReport, VLMClient

__version__ = "0.1.0"

__all__ = [
    "PAPER_DELTA",
    "CachedEncoder",
    "DataError",
    "Dataset",
    "DetectionTrace",
    "DetectorSession",
    "Encoder",
    "EncoderError",
    "EncoderMismatchError",
    "FailureDetector",
    "FailureMemory",
    "FailureReport",
    "Frame",
    "MemoryEntry",
    "MemoryFormatError",
    "Neighbor",
    "Outcome",
    "RoboFailRingError",
    "SettingError",
    "StepResult",
    "StepSink",
    "SymbolError",
    "Trajectory",
    "UnknownTaskError",
    "VLMClient",
    "ground",
    "load_dataset",
    "load_encoder",
    "load_trajectory",
    "pair_vectors",
    "parse_symbol",
]
