"""Data model and dataset loaders."""

from __future__ import annotations

from robofailring.data.layouts import LAYOUTS_HELP, Dataset, detect_layout, load_dataset, load_trajectory
from robofailring.data.model import Frame, Outcome, Trajectory

__all__ = [
    "LAYOUTS_HELP",
    "Dataset",
    "Frame",
    "Outcome",
    "Trajectory",
    "detect_layout",
    "load_dataset",
    "load_trajectory",
]
