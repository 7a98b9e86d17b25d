"""The AHA FailGen layout: `<root>[/<task>]/<task>_<failtype>_wp<k>_episode<e>/<view>_<idx>.png`.

Episode names say the task and the failure (paper, AHA FailGen); a name that looks like one but
names an unknown failure type is reported with the known ones. A dataset's own symbols (its
`--vocabulary`) name failures too: `<task>_<symbol>[_wp<k>]_episode<e>`, matched before Table 5's, so
`pick_cube_slip_twice_wp3_episode0` is the vocabulary's `slip_twice`, not Table 5's `slip`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Final

from robofailring.data.grounding import Vocabulary
from robofailring.data.layouts.folders import beside, episode_views, subdirs
from robofailring.data.layouts.project import folder_signals
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.model import Outcome, Skipped, Trajectory

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


def _own_name(vocabulary: Vocabulary | None) -> re.Pattern[str] | None:
    """An episode name with one of the vocabulary's symbols (the longest first), None without one."""
    if vocabulary is None or not vocabulary.symbols:
        return None
    symbols = "|".join(re.escape(symbol) for symbol in sorted(vocabulary.symbols, key=len, reverse=True))
    return re.compile(rf"^(?P<task>.+?)_(?P<fail>{symbols})(?:_wp(?P<wp>\d+))?_episode(?P<ep>\d+)$")


def parse_aha_name(name: str, vocabulary: Vocabulary | None = None) -> tuple[str, str | None, str] | None:
    """(task, symbol or None for success, episode number) from an AHA-style folder name; `vocabulary`: the
    dataset's own symbols, which name failures too."""
    own = _own_name(vocabulary)
    if own is not None and (match := own.match(name)):
        symbol = match["fail"] if match["wp"] is None else f"{match['fail']}_wp{match['wp']}"
        return match["task"], symbol, match["ep"]
    if match := _AHA_WAYPOINT.match(name):
        return match["task"], f"{match['fail']}_wp{match['wp']}", match["ep"]
    if match := _AHA_WRONG_OBJECT.match(name):
        symbol = "wrong_object" if match["wp"] is None else f"wrong_object_wp{match['wp']}"
        return match["task"], symbol, match["ep"]
    if match := _AHA_SUCCESS.match(name):
        return match["task"], None, match["ep"]
    return None


def aha_name_problem(name: str, vocabulary: Vocabulary | None = None) -> str:
    """Why a folder name is not an AHA episode name, naming the unknown failure token if there is one."""
    if match := _AHA_LIKE.match(name):
        own = sorted(vocabulary.symbols) if vocabulary is not None else []
        hint = "" if own else "; a dataset's own failure symbols: pass --vocabulary FILE"
        return (
            f"unknown failure type {match['token']!r} in episode name {name!r} "
            f"(known: {', '.join((*AHA_FAILURES, 'wrong_object', *own))}{hint})"
        )
    return "name is not <task>_<failtype>_wp<k>_episode<e>, <task>_wrong_object[_wp<k>]_episode<e> or <task>_success_episode<e>"


def aha_trajectories(root: Path, *, first_only: bool = False, vocabulary: Vocabulary | None = None) -> Found:
    """The AHA-named episode folders directly under `root`, or one level down (grouped per task)."""
    top = subdirs(root)
    skipped: list[Skipped] = []
    found = _aha_level(root, top, skipped, first_only=first_only, vocabulary=vocabulary)
    if found:
        return found, skipped + beside(root, "a file beside the episode folders")
    skipped = []
    for group in top:
        group_skipped: list[Skipped] = []
        episodes = _aha_level(
            root, subdirs(group), group_skipped, first_only=first_only, vocabulary=vocabulary
        )
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
    root: Path,
    folders: list[Path],
    skipped: list[Skipped],
    *,
    first_only: bool,
    vocabulary: Vocabulary | None,
) -> list[Trajectory]:
    found = []
    for directory in folders:
        parsed = parse_aha_name(directory.name, vocabulary)
        if parsed is None:
            skipped.append(Skipped(directory, aha_name_problem(directory.name, vocabulary)))
            continue
        views, inside = episode_views(directory)
        if not views:
            skipped.append(Skipped(directory, "no images or videos in this episode folder"))
            continue
        task, symbol, _ = parsed
        episode = directory.name if directory.parent == root else f"{directory.parent.name}/{directory.name}"
        signals, signals_file = folder_signals(directory)  # episodes of the project's copied out of it
        inside = [item for item in inside if signals_file is None or item.path.name != signals_file]
        found.append(
            Trajectory(
                task=task,
                episode=episode,
                views=views,
                symbol=symbol,
                outcome=Outcome.FAILURE if symbol else Outcome.SUCCESS,
                source=directory,
                skipped=tuple(inside),
                signals=signals,
            )
        )
        if first_only:
            break
    return found


def _detect(root: Path) -> bool:
    return bool(aha_trajectories(root, first_only=True)[0])


def _read(root: Path, *, task: str | None = None, vocabulary: Vocabulary | None = None) -> Found:
    return aha_trajectories(root, vocabulary=vocabulary)


LAYOUT: Final = register(
    Layout(
        name="aha",
        detect=_detect,
        read=_read,
        help="the AHA FailGen layout <root>/<task>_<failtype>_wp<k>_episode<e>/{front,overhead,wrist}_<idx>.png "
        "(or <task>_wrong_object[_wp<k>]_episode<e>)",
        listed=2,
        detect_order=80,  # named image episodes before the images of any names
        names_symbols=True,
    )
)
