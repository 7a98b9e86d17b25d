"""The ManiSkill-failgen/FailSafe layout: `<root>/<task>/<seed>/{Ground_Truth | <ep>_<fail>_<stage>}/<view>/<n>.png`."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Final

from robofailring.data.layouts.folders import beside, episode_views, subdirs
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.model import Outcome, Skipped, Trajectory

MANISKILL_SUCCESS: Final[str] = "Ground_Truth"
MANISKILL_FAILURES: Final[tuple[str, ...]] = (
    "grasp",
    "trans_x",
    "trans_y",
    "trans_z",
    "rot_x",
    "rot_y",
    "rot_z",
)
MANISKILL_FAILURE = re.compile(
    r"^(?P<ep>\d+)_(?P<fail>" + "|".join(MANISKILL_FAILURES) + r")_(?P<stage>[^_]+)$"
)


def maniskill_trajectories(root: Path, *, first_only: bool = False) -> Found:
    """`<root>/<task>/<seed>/<episode>`; the root may also be one task's or one seed's folder."""
    levels = [[root]]
    for _ in range(3):
        levels.append([child for parent in levels[-1] for child in subdirs(parent)])
    for depth in (3, 2, 1):
        found: list[Trajectory] = []
        skipped: list[Skipped] = []
        for directory in levels[depth]:
            failure = MANISKILL_FAILURE.match(directory.name)
            if directory.name != MANISKILL_SUCCESS and failure is None:
                skipped.append(
                    Skipped(
                        directory,
                        f"not a ManiSkill-failgen episode folder ({MANISKILL_SUCCESS} or <ep>_<fail>_<stage>, "
                        f"fail one of {', '.join(MANISKILL_FAILURES)})",
                    )
                )
                continue
            views, inside = episode_views(directory)
            if not views:
                skipped.append(Skipped(directory, "no images or videos in this episode folder"))
                continue
            absolute = Path(os.path.abspath(directory))  # names above `root`, links kept
            found.append(
                Trajectory(
                    task=absolute.parent.parent.name,
                    episode=f"{absolute.parent.name}/{directory.name}",
                    views=views,
                    symbol=f"{failure['fail']}_{failure['stage']}" if failure else None,
                    outcome=Outcome.FAILURE if failure else Outcome.SUCCESS,
                    source=directory,
                    skipped=tuple(inside),
                )
            )
            if first_only:
                return found, []
        if found:
            for level in levels[:depth]:
                for parent in level:
                    skipped += beside(parent, "a file where episode folders are expected")
                    if not subdirs(parent):
                        skipped.append(Skipped(parent, "holds no episode folder"))
            return found, skipped
    return [], []


def _detect(root: Path) -> bool:
    return bool(maniskill_trajectories(root, first_only=True)[0])


def _read(root: Path, *, task: str | None = None) -> Found:
    return maniskill_trajectories(root)


LAYOUT: Final = register(
    Layout(
        name="maniskill",
        detect=_detect,
        read=_read,
        help="the ManiSkill-failgen/FailSafe layout "
        "<root>/<task>/<seed>/{Ground_Truth | <ep>_<fail>_<stage>}/{front,side,wrist}/<n>.png",
        listed=3,
        detect_order=90,  # named image episodes before the images of any names
    )
)
