"""The record each data layout module registers: its name, how it is recognised, how it is read, and when.

Each layout module of this package registers its record with `register` when imported (the package imports
every module in it); `in_detection_order` lists the records in the order their `detect_order` gives
(docs/architecture.md, data/), and `layouts_help` lists every one for the "matches no known dataset layout"
error. A new layout is one module here: nothing else lists the layouts.
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
    detect_order: int  # layouts are tried in ascending order: the first whose `detect` says yes reads a root
    manifest: Callable[[Path], dict[str, Any]] | None = None  # the layout's own manifest, if it has one
    reads_files: bool = False  # True: a root may be one file of this layout (an HDF5 file), not a folder
    # True: its folder names say the failure, so `read` also takes `vocabulary=` (a dataset's own symbols)
    names_symbols: bool = False


_REGISTERED: list[Layout] = []


def register(layout: Layout) -> Layout:
    """Add a layout module's record to the registry (each module calls this once, at import); a name, a number
    in the error's list or a place in the detection order another layout has is a ValueError naming both (two
    layouts at one place would be tried in whichever order their modules were imported)."""
    for other in _REGISTERED:
        for what in ("name", "listed", "detect_order"):
            if getattr(other, what) == getattr(layout, what):
                raise ValueError(
                    f"layout {layout.name!r} has the {what} {getattr(layout, what)!r} of layout {other.name!r}"
                )
    _REGISTERED.append(layout)
    return layout


def layouts_help() -> str:
    """Every registered layout and how it looks, in the order of their numbers."""
    return "expected one of: " + "; ".join(
        f"({layout.listed}) {layout.help}" for layout in sorted(_REGISTERED, key=lambda layout: layout.listed)
    )


def in_detection_order() -> tuple[Layout, ...]:
    """Every registered layout, in the order roots are tried against them."""
    return tuple(sorted(_REGISTERED, key=lambda layout: layout.detect_order))
