"""The AHA FailGen layout: `<root>[/<task>]/<task>_<failtype>_wp<k>_episode<e>/<view>_<idx>.png`.

Episode names say the task and the failure (paper, AHA FailGen); a name that looks like one but
names an unknown failure type is reported with the known ones.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Final

from robofailring.data.folders import beside, episode_views, subdirs
from robofailring.data.model import Outcome, Skipped, Trajectory
from robofailring.data.registry import Found, Layout, register

AHA_FAILURES: Final[tuple[str, ...]] = (
    "no_rotation",
    "wrong_sequence",
    "translation_x",
    "translation_y",
    "translation_z",
    "rotation_x",
    "rotation_y",
    "rotation_z",
    "grasp",
    "slip",
)
_AHA_WAYPOINT = re.compile(
    r"^(?P<task>.+?)_(?P<fail>" + "|".join(AHA_FAILURES) + r")_wp(?P<wp>\d+)_episode(?P<ep>\d+)$"
)
_AHA_WRONG_OBJECT = re.compile(r"^(?P<task>.+)_wrong_object(?:_wp(?P<wp>\d+))?_episode(?P<ep>\d+)$")
_AHA_SUCCESS = re.compile(r"^(?P<task>.+)_success_episode(?P<ep>\d+)$")
_AHA_LIKE = re.compile(r"^(?P<head>.+)_(?P<token>[^_]+)_wp\d+_episode\d+$")


def parse_aha_name(name: str) -> tuple[str, str | None, str] | None:
    """(task, symbol or None for success, episode number) from an AHA-style folder name."""
    if match := _AHA_WAYPOINT.match(name):
        return match["task"], f"{match['fail']}_wp{match['wp']}", match["ep"]
    if match := _AHA_WRONG_OBJECT.match(name):
        symbol = "wrong_object" if match["wp"] is None else f"wrong_object_wp{match['wp']}"
        return match["task"], symbol, match["ep"]
    if match := _AHA_SUCCESS.match(name):
        return match["task"], None, match["ep"]
    return None


def aha_name_problem(name: str) -> str:
    """Why a folder name is not an AHA episode name, naming the unknown failure token if there is one."""
    if match := _AHA_LIKE.match(name):
        return (
            f"unknown failure type {match['token']!r} in episode name {name!r} "
            f"(known: {', '.join((*AHA_FAILURES, 'wrong_object'))})"
        )
    return "name is not <task>_<failtype>_wp<k>_episode<e>, <task>_wrong_object[_wp<k>]_episode<e> or <task>_success_episode<e>"


def aha_trajectories(root: Path, *, first_only: bool = False) -> Found:
    """The AHA-named episode folders directly under `root`, or one level down (grouped per task)."""
    top = subdirs(root)
    skipped: list[Skipped] = []
    found = _aha_level(root, top, skipped, first_only=first_only)
    if found:
        return found, skipped + beside(root, "a file beside the episode folders")
    skipped = []
    for group in top:
        group_skipped: list[Skipped] = []
        episodes = _aha_level(root, subdirs(group), group_skipped, first_only=first_only)
        if first_only and episodes:
            return episodes, []
        if episodes:
            found += episodes
            skipped += group_skipped
            skipped += beside(group, "a file beside the episode folders")
        else:
            skipped.append(Skipped(group, "holds no AHA episode folder"))
    if found:
        skipped += beside(root, "a file beside the task folders")
    return found, skipped


def _aha_level(
    root: Path, folders: list[Path], skipped: list[Skipped], *, first_only: bool
) -> list[Trajectory]:
    found = []
    for directory in folders:
        parsed = parse_aha_name(directory.name)
        if parsed is None:
            skipped.append(Skipped(directory, aha_name_problem(directory.name)))
            continue
        views, inside = episode_views(directory)
        if not views:
            skipped.append(Skipped(directory, "no images or videos in this episode folder"))
            continue
        task, symbol, _ = parsed
        episode = directory.name if directory.parent == root else f"{directory.parent.name}/{directory.name}"
        found.append(
            Trajectory(
                task=task,
                episode=episode,
                views=views,
                symbol=symbol,
                outcome=Outcome.FAILURE if symbol else Outcome.SUCCESS,
                source=directory,
                skipped=tuple(inside),
            )
        )
        if first_only:
            break
    return found


def _detect(root: Path) -> bool:
    return bool(aha_trajectories(root, first_only=True)[0])


def _read(root: Path, *, task: str | None = None) -> Found:
    return aha_trajectories(root)


LAYOUT: Final = register(
    Layout(
        name="aha",
        detect=_detect,
        read=_read,
        help="the AHA FailGen layout <root>/<task>_<failtype>_wp<k>_episode<e>/{front,overhead,wrist}_<idx>.png "
        "(or <task>_wrong_object[_wp<k>]_episode<e>)",
        listed=2,
    )
)
