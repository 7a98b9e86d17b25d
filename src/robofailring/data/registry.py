"""The record each data layout module registers: its name, how it is recognised, how it is read.

`robofailring.data.layouts.LAYOUTS` lists the records in detection order (docs/architecture.md, data/).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robofailring.data.model import Skipped, Trajectory

Found = tuple[list[Trajectory], list[Skipped]]


@dataclass(frozen=True)
class Layout:
    """One dataset layout: `detect(root)` says whether a root is of it, `read(root, task=)` reads it."""

    name: str
    detect: Callable[[Path], bool]
    read: Callable[..., Found]  # read(root, *, task: str | None) -> (trajectories, skipped)
    help: str  # how the layout looks, for the "matches no known dataset layout" error
    listed: int  # its number in that error's list
    manifest: Callable[[Path], dict[str, Any]] | None = None  # the layout's own manifest, if it has one
