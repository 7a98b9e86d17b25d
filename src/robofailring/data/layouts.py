"""Dataset layouts (SPEC §4): AHA FailGen, ManiSkill-failgen/FailSafe, the project's own, one episode."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from robofailring.data.images import IMAGE_SUFFIXES, numeric_sort_key
from robofailring.data.model import Frame, Outcome, Trajectory
from robofailring.errors import DataError

PROJECT_MANIFEST: Final[str] = "manifest.json"
PROJECT_FORMAT: Final[str] = "robofailring-dataset"

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
_AHA_WRONG_OBJECT = re.compile(r"^(?P<task>.+)_wrong_object_episode(?P<ep>\d+)$")
_AHA_SUCCESS = re.compile(r"^(?P<task>.+)_success_episode(?P<ep>\d+)$")
_AHA_FRAME = re.compile(r"^(?P<view>.+)_(?P<idx>\d+)$")
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
_MANISKILL_FAILURE = re.compile(
    r"^(?P<ep>\d+)_(?P<fail>" + "|".join(MANISKILL_FAILURES) + r")_(?P<stage>[^_]+)$"
)

LAYOUTS_HELP: Final[str] = (
    "expected one of: (1) the project's own layout (a manifest.json written by `robofailring generate`); "
    "(2) the AHA FailGen layout <root>/<task>_<failtype>_wp<k>_episode<e>/{front,overhead,wrist}_<idx>.png "
    "(or <task>_wrong_object_episode<e>); (3) the ManiSkill-failgen/FailSafe layout "
    "<root>/<task>/<seed>/{Ground_Truth | <ep>_<fail>_<stage>}/{front,side,wrist}/<n>.png; "
    "(4) one episode: <dir>/{<view>}/<n>.png"
)


def _images(directory: Path) -> list[Path]:
    return sorted(
        (p for p in directory.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES),
        key=numeric_sort_key,
    )


def parse_aha_name(name: str) -> tuple[str, str | None, str] | None:
    """(task, symbol or None for success, episode number) from an AHA-style folder name."""
    if match := _AHA_WAYPOINT.match(name):
        return match["task"], f"{match['fail']}_wp{match['wp']}", match["ep"]
    if match := _AHA_WRONG_OBJECT.match(name):
        return match["task"], "wrong_object", match["ep"]
    if match := _AHA_SUCCESS.match(name):
        return match["task"], None, match["ep"]
    return None


def aha_views(directory: Path) -> dict[str, tuple[Frame, ...]]:
    """Frames of an AHA-style episode folder, grouped by the view prefix of `<view>_<idx>.png`."""
    grouped: dict[str, list[Path]] = {}
    for path in _images(directory):
        match = _AHA_FRAME.match(path.stem)
        if match:
            grouped.setdefault(match["view"], []).append(path)
    return {
        view: tuple(Frame(path=p) for p in sorted(paths, key=numeric_sort_key))
        for view, paths in sorted(grouped.items())
    }


def folder_views(directory: Path) -> dict[str, tuple[Frame, ...]]:
    """Frames of an episode stored as one sub-folder of numbered images per view."""
    views: dict[str, tuple[Frame, ...]] = {}
    for sub in sorted(p for p in directory.iterdir() if p.is_dir()):
        images = _images(sub)
        if images:
            views[sub.name] = tuple(Frame(path=p) for p in images)
    return views


@dataclass(frozen=True)
class Dataset:
    """A dataset root and its layout; trajectories are listed lazily, frames decoded on demand."""

    root: Path
    layout: str
    manifest: dict[str, Any] | None = None
    task_override: str | None = None

    def __iter__(self) -> Iterator[Trajectory]:
        return self.trajectories()

    def trajectories(self) -> Iterator[Trajectory]:
        if self.layout == "project":
            yield from _project_trajectories(self.root, self.manifest or {})
        elif self.layout == "aha":
            yield from _aha_trajectories(self.root)
        elif self.layout == "maniskill":
            yield from _maniskill_trajectories(self.root)
        else:
            yield _episode_trajectory(self.root, task=self.task_override)

    def select(self, *, split: str | None = None, keys: list[str] | None = None) -> list[Trajectory]:
        """Trajectories of a split and/or with given keys (`<task>/<episode>` or the episode alone)."""
        chosen = []
        for trajectory in self.trajectories():
            if split is not None and trajectory.split != split:
                continue
            if keys and trajectory.key not in keys and trajectory.episode not in keys:
                continue
            chosen.append(trajectory)
        if keys:
            found = {t.key for t in chosen} | {t.episode for t in chosen}
            missing = [k for k in keys if k not in found]
            if missing:
                raise DataError(f"no trajectory {missing[0]!r} in {self.root} ({self.layout} layout)")
        return chosen


def detect_layout(root: Path) -> str:
    """The layout name of a dataset root, or DataError naming the layouts expected."""
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"dataset root {root} is not a directory")
    if (root / PROJECT_MANIFEST).is_file():
        return "project"
    if _aha_episodes(root, first_only=True):
        return "aha"
    if _maniskill_episodes(root, first_only=True):
        return "maniskill"
    if _episode_views(root):
        return "episode"
    raise DataError(f"{root} matches no known dataset layout; {LAYOUTS_HELP}")


def load_dataset(root: Path, *, task: str | None = None) -> Dataset:
    """Open a dataset root of any supported layout (auto-detected)."""
    root = Path(root)
    layout = detect_layout(root)
    manifest = None
    if layout == "project":
        manifest = read_project_manifest(root)
    return Dataset(root=root, layout=layout, manifest=manifest, task_override=task)


def load_trajectory(path: Path, *, task: str | None = None) -> Trajectory:
    """One trajectory from an episode folder of any layout (AHA-style files or view sub-folders).

    The task comes from the folder name where the layout encodes it, else from `task`.
    """
    path = Path(path)
    if not path.is_dir():
        raise DataError(f"trajectory {path} is not a directory")
    if (path / PROJECT_MANIFEST).is_file() or detect_layout(path) != "episode":
        dataset = load_dataset(path)
        found = list(dataset.trajectories())
        if len(found) != 1:
            raise DataError(
                f"{path} is a {dataset.layout} dataset with {len(found)} trajectories; pass one of its episode "
                "folders (or replay the whole dataset with `robofailring replay`)"
            )
        return found[0]
    parent_manifest = path.parent / PROJECT_MANIFEST
    if parent_manifest.is_file():
        for trajectory in _project_trajectories(path.parent, read_project_manifest(path.parent)):
            if trajectory.source is not None and trajectory.source.resolve() == path.resolve():
                return trajectory
    return _episode_trajectory(path, task=task)


def _episode_trajectory(path: Path, *, task: str | None) -> Trajectory:
    parsed = parse_aha_name(path.name)
    views = _episode_views(path)
    if not views:
        raise DataError(f"{path} holds no images; {LAYOUTS_HELP}")
    symbol: str | None = None
    outcome: Outcome | None = None
    episode = path.name
    if parsed is not None:
        parsed_task, symbol, _ = parsed
        task = task or parsed_task
        outcome = Outcome.FAILURE if symbol else Outcome.SUCCESS
    else:
        maniskill = _MANISKILL_FAILURE.match(path.name)
        if maniskill is not None:
            symbol = f"{maniskill['fail']}_{maniskill['stage']}"
            outcome = Outcome.FAILURE
        elif path.name == MANISKILL_SUCCESS:
            outcome = Outcome.SUCCESS
        if task is None and (maniskill is not None or path.name == MANISKILL_SUCCESS):
            task = path.parent.parent.name
            episode = f"{path.parent.name}/{path.name}"
    if task is None:
        unknown = re.match(r"^.+?_(?P<fail>[^_]+)_wp\d+_episode\d+$", path.name)
        if unknown is not None:
            raise DataError(
                f"{path}: unknown failure type {unknown['fail']!r} in the folder name "
                f"(known: {', '.join(AHA_FAILURES)}, wrong_object, success); rename the folder"
            )
        raise DataError(f"cannot tell the task of trajectory {path} from its name; pass it with --task")
    return Trajectory(task=task, episode=episode, views=views, symbol=symbol, outcome=outcome, source=path)


def _natural_key(path: Path) -> list[tuple[int, int | str]]:
    """`episode2` before `episode10`, `seed 3` before `seed 10`; names otherwise alphabetical."""
    return [(0, int(part)) if part.isdigit() else (1, part) for part in re.split(r"(\d+)", path.name)]


def _subdirs(directory: Path) -> list[Path]:
    return sorted(
        (p for p in directory.iterdir() if p.is_dir() and not p.name.startswith(".")), key=_natural_key
    )


Views = dict[str, tuple[Frame, ...]]  # view name -> its frames in order


def _episode_views(directory: Path) -> Views:
    """Views of an episode folder: `<view>_<idx>.png` files, else one sub-folder of images per view."""
    return aha_views(directory) or folder_views(directory)


def _aha_episodes(
    root: Path, *, first_only: bool = False
) -> list[tuple[Path, tuple[str, str | None, str], Views]]:
    """(folder, parsed name, views) of the AHA-named episode folders directly under `root`, or one
    level down (e.g. grouped per task). With `first_only`, stop at the first one (enough to
    recognise the layout)."""
    top = _subdirs(root)
    levels: list[Iterator[Path]] = [
        iter(top),
        (episode for group in top if parse_aha_name(group.name) is None for episode in _subdirs(group)),
    ]
    for level in levels:
        found = []
        for directory in level:
            parsed = parse_aha_name(directory.name)
            views = _episode_views(directory) if parsed else {}
            if parsed and views:
                found.append((directory, parsed, views))
                if first_only:
                    return found
        if found:
            return found
    return []


def _maniskill_episodes(root: Path, *, first_only: bool = False) -> list[tuple[str, str, Path, Views]]:
    """(task, seed, episode folder, views) of a ManiSkill-failgen root: `<root>/<task>/<seed>/<episode>`.

    A root that is one task's folder or one seed's folder also reads; the task then comes from
    the path. With `first_only`, stop at the first episode found (enough to recognise the layout).
    """
    levels = [[root]]
    for _ in range(3):
        levels.append([child for parent in levels[-1] for child in _subdirs(parent)])
    for candidates in (levels[3], levels[2], levels[1]):
        found = []
        for directory in candidates:
            named = directory.name == MANISKILL_SUCCESS or _MANISKILL_FAILURE.match(directory.name)
            views = folder_views(directory) if named else {}
            if views:
                absolute = Path(os.path.abspath(directory))  # names above `root`, links kept
                found.append((absolute.parent.parent.name, absolute.parent.name, directory, views))
                if first_only:
                    break
        if found:
            return found
    return []


def _aha_trajectories(root: Path) -> Iterator[Trajectory]:
    for directory, (task, symbol, _), views in _aha_episodes(root):
        episode = directory.name if directory.parent == root else f"{directory.parent.name}/{directory.name}"
        yield Trajectory(
            task=task,
            episode=episode,
            views=views,
            symbol=symbol,
            outcome=Outcome.FAILURE if symbol else Outcome.SUCCESS,
            source=directory,
        )


def _maniskill_trajectories(root: Path) -> Iterator[Trajectory]:
    for task, seed, episode_dir, views in _maniskill_episodes(root):
        failure = _MANISKILL_FAILURE.match(episode_dir.name)  # else it is Ground_Truth, a success
        yield Trajectory(
            task=task,
            episode=f"{seed}/{episode_dir.name}",
            views=views,
            symbol=f"{failure['fail']}_{failure['stage']}" if failure else None,
            outcome=Outcome.FAILURE if failure else Outcome.SUCCESS,
            source=episode_dir,
        )


def read_project_manifest(root: Path) -> dict[str, Any]:
    """The project's dataset manifest, validated enough to name what is wrong."""
    path = Path(root) / PROJECT_MANIFEST
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as error:
        raise DataError(f"cannot read dataset manifest {path}: {error}") from error
    if manifest.get("format") != PROJECT_FORMAT or not isinstance(manifest.get("episodes"), list):
        raise DataError(f"{path} is not a robofailring dataset manifest (format {PROJECT_FORMAT!r})")
    return dict(manifest)


def _project_trajectories(root: Path, manifest: dict[str, Any]) -> Iterator[Trajectory]:
    for record in manifest["episodes"]:
        try:
            directory = root / record["dir"]
            outcome = Outcome(record["outcome"])
            task = record["task"]
        except (KeyError, ValueError) as error:
            raise DataError(f"{root / PROJECT_MANIFEST}: bad episode record {record!r} ({error})") from error
        if not directory.is_dir():
            raise DataError(f"{root / PROJECT_MANIFEST} lists {record['dir']} but {directory} is missing")
        views = aha_views(directory)
        wanted = record.get("views")
        if wanted:
            views = {view: views.get(view, ()) for view in wanted}
        yield Trajectory(
            task=task,
            episode=record.get("episode", record["dir"]),
            views=views,
            symbol=record.get("label"),
            outcome=outcome,
            source=directory,
            fps=record.get("fps", manifest.get("fps")),
            split=record.get("split"),
        )
