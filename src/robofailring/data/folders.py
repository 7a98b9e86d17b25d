"""Episode folders of images or videos, and the AHA and ManiSkill-failgen layouts that hold them.

Every function here returns what it read *and* what it did not read (`Skipped`, with the reason):
nothing under a dataset root is dropped silently. Hidden names (starting with `.`) are ignored.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Final

from robofailring.data.images import IMAGE_SUFFIXES
from robofailring.data.model import Frame, Outcome, Skipped, Trajectory
from robofailring.data.video import VIDEO_SUFFIXES, VideoFrames, open_video
from robofailring.errors import DataError

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
_AHA_FRAME = re.compile(r"^(?P<view>.+)_(?P<idx>\d+)$")
_LAST_NUMBER = re.compile(r"(\d+)(?!.*\d)")
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

Views = dict[str, Sequence[Frame]]  # view name -> its frames in order
Found = tuple[list[Trajectory], list[Skipped]]


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


def _visible(directory: Path) -> list[Path]:
    return sorted((p for p in directory.iterdir() if not p.name.startswith(".")), key=natural_key)


def natural_key(path: Path) -> list[tuple[int, int | str]]:
    """`episode2` before `episode10`, `seed 3` before `seed 10`; names otherwise alphabetical."""
    return [(0, int(part)) if part.isdigit() else (1, part) for part in re.split(r"(\d+)", path.name)]


def subdirs(directory: Path) -> list[Path]:
    return [p for p in _visible(directory) if p.is_dir()]


def _is_image(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in IMAGE_SUFFIXES


def _numbered(paths: Sequence[tuple[Path, int]], where: Path, *, view: str) -> tuple[Frame, ...]:
    """Frames ordered by number; two files with one number are an error naming both."""
    seen: dict[int, Path] = {}
    for path, number in paths:
        if number in seen:
            raise DataError(
                f"two frames numbered {number} in view {view!r} of {where}: {seen[number].name} and {path.name}; "
                "rename or remove one (which one is frame "
                f"{number} cannot be decided)"
            )
        seen[number] = path
    return tuple(Frame(path=seen[number]) for number in sorted(seen))


def _unnumbered(where: Path, names: list[str], pattern: str) -> Skipped:
    shown = ", ".join(names[:3]) + (", …" if len(names) > 3 else "")
    return Skipped(
        where, f"{len(names)} image(s) without a frame number ({shown}); frames are named {pattern}"
    )


def aha_files(directory: Path) -> tuple[Views, list[Skipped]]:
    """Frames of an episode folder of `<view>_<idx>.png` files, grouped by view."""
    grouped: dict[str, list[tuple[Path, int]]] = {}
    unnumbered: list[str] = []
    for path in _visible(directory):
        if not _is_image(path):
            continue
        match = _AHA_FRAME.match(path.stem)
        if match:
            grouped.setdefault(match["view"], []).append((path, int(match["idx"])))
        else:
            unnumbered.append(path.name)
    views: Views = {view: _numbered(paths, directory, view=view) for view, paths in sorted(grouped.items())}
    skipped = [_unnumbered(directory, unnumbered, "<view>_<index>.<ext>")] if unnumbered else []
    return views, skipped


def view_folders(directory: Path) -> tuple[Views, list[Skipped]]:
    """Frames of an episode stored as one sub-folder of numbered images per view."""
    views: Views = {}
    skipped: list[Skipped] = []
    for sub in subdirs(directory):
        numbered: list[tuple[Path, int]] = []
        unnumbered: list[str] = []
        others: list[str] = []
        for path in _visible(sub):
            if _is_image(path):
                match = _LAST_NUMBER.search(path.stem)
                if match:
                    numbered.append((path, int(match.group(1))))
                else:
                    unnumbered.append(path.name)
            else:
                others.append(path.name)
        if numbered:
            views[sub.name] = _numbered(numbered, sub, view=sub.name)
        if unnumbered:
            skipped.append(_unnumbered(sub, unnumbered, "<index>.<ext>"))
        if others and (numbered or unnumbered):
            skipped += [
                Skipped(sub / name, "not an image (.png, .jpg, .jpeg, .bmp, .webp)") for name in others
            ]
        elif not numbered and not unnumbered:
            skipped.append(Skipped(sub, "no images in this view folder"))
    return views, skipped


def video_views(directory: Path) -> Views:
    """One view per video file of the folder (`<view>.mp4|.webm|.mkv`), decoded lazily."""
    return {
        path.stem: VideoFrames(open_video(path))
        for path in _visible(directory)
        if path.is_file() and path.suffix.lower() in VIDEO_SUFFIXES
    }


def episode_views(directory: Path) -> tuple[Views, list[Skipped]]:
    """Views of an episode folder: `<view>_<idx>` images, else view sub-folders, else `<view>.mp4` videos.

    Whatever else the folder holds is returned as skipped, with the reason.
    """
    visible = _visible(directory)
    views, skipped = aha_files(directory)
    if views or skipped:
        kind, others = "images named <view>_<index>", [p for p in visible if not _is_image(p)]
    else:
        views, skipped = view_folders(directory)
        kind, others = "view folders", [p for p in visible if not p.is_dir()]
        if not views:
            views, skipped = video_views(directory), []
            kind = "videos"
            others = [p for p in visible if not (p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES)]
    if views:
        skipped += [Skipped(p, f"not part of an episode stored as {kind}") for p in others]
    return views, skipped


def aha_trajectories(root: Path, *, first_only: bool = False) -> Found:
    """The AHA-named episode folders directly under `root`, or one level down (grouped per task)."""
    top = subdirs(root)
    skipped: list[Skipped] = []
    found = _aha_level(root, top, skipped, first_only=first_only)
    if found:
        for path in _visible(root):
            if path.is_file():
                skipped.append(Skipped(path, "a file beside the episode folders"))
        return found, skipped
    skipped = []
    for group in top:
        group_skipped: list[Skipped] = []
        episodes = _aha_level(root, subdirs(group), group_skipped, first_only=first_only)
        if first_only and episodes:
            return episodes, []
        if episodes:
            found += episodes
            skipped += group_skipped
            skipped += [
                Skipped(p, "a file beside the episode folders") for p in _visible(group) if p.is_file()
            ]
        else:
            skipped.append(Skipped(group, "holds no AHA episode folder"))
    if found:
        skipped += [Skipped(p, "a file beside the task folders") for p in _visible(root) if p.is_file()]
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
                    skipped += [
                        Skipped(p, "a file where episode folders are expected")
                        for p in _visible(parent)
                        if p.is_file()
                    ]
                    if not subdirs(parent):
                        skipped.append(Skipped(parent, "holds no episode folder"))
            return found, skipped
    return [], []
