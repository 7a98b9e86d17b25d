"""One episode folder: `<dir>/{<view>}/<n>.png`, `<dir>/<view>_<n>.png`, `<dir>/<n>.png` or `<dir>/<view>.mp4`.

The task and outcome come from the folder name where it follows the AHA or ManiSkill naming, else
from `--task`. Read as a dataset (`load_dataset`: build-memory, evaluate, …), a folder whose views
are sub-folders of images could also be a root of episodes of one camera each (`runs/run_0/000.png`);
it is read as one episode (docs/data.md, "One camera per episode"), with a warning saying so and how to name the
images for the other reading.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Final

from robofailring.data.grounding import Vocabulary
from robofailring.data.layouts.aha import aha_name_problem, parse_aha_name
from robofailring.data.layouts.folders import camera_named, episode_views
from robofailring.data.layouts.maniskill import MANISKILL_FAILURE, MANISKILL_SUCCESS
from robofailring.data.layouts.project import folder_signals
from robofailring.data.layouts.registry import Found, Layout, layouts_help, register
from robofailring.data.model import Outcome, Trajectory
from robofailring.errors import DataError

_log = logging.getLogger("robofailring")


def episode_trajectory(path: Path, *, task: str | None, vocabulary: Vocabulary | None = None) -> Trajectory:
    """The episode folder `path`: its task and failure from its name (`vocabulary`: the dataset's own
    symbols, which name failures too), else `task`."""
    parsed = parse_aha_name(path.name, vocabulary)
    views, skipped = episode_views(path)
    if not views:
        raise DataError(f"{path} holds no images; {layouts_help()}")
    signals, signals_file = folder_signals(path)  # a project episode copied without its dataset's manifest
    skipped = [item for item in skipped if signals_file is None or item.path.name != signals_file]
    symbol: str | None = None
    outcome: Outcome | None = None
    episode = path.name
    if parsed is not None:
        parsed_task, symbol, _ = parsed
        task = task or parsed_task
        outcome = Outcome.FAILURE if symbol else Outcome.SUCCESS
    else:
        maniskill = MANISKILL_FAILURE.match(path.name)
        if maniskill is not None:
            symbol = f"{maniskill['fail']}_{maniskill['stage']}"
            outcome = Outcome.FAILURE
        elif path.name == MANISKILL_SUCCESS:
            outcome = Outcome.SUCCESS
        if task is None and (maniskill is not None or path.name == MANISKILL_SUCCESS):
            task = path.parent.parent.name
            episode = f"{path.parent.name}/{path.name}"
    if task is None:
        problem = aha_name_problem(path.name, vocabulary)
        if problem.startswith("unknown failure type"):
            raise DataError(f"cannot read trajectory {path}: {problem}")
        raise DataError(f"cannot tell the task of trajectory {path} from its name; pass it with --task")
    return Trajectory(
        task=task,
        episode=episode,
        views=views,
        symbol=symbol,
        outcome=outcome,
        source=path,
        skipped=tuple(skipped),
        signals=signals,
    )


def _detect(root: Path) -> bool:
    return bool(episode_views(root)[0])


def _read(root: Path, *, task: str | None = None, vocabulary: Vocabulary | None = None) -> Found:
    trajectory = episode_trajectory(root, task=task, vocabulary=vocabulary)
    folders = [view for view in trajectory.views if (root / view).is_dir()]
    plain = all(camera_named(root / view) is None for view in folders)  # no file name says a camera
    if len(folders) >= 2 and plain and trajectory.outcome is None:  # an AHA or ManiSkill name says "episode"
        shown = ", ".join(folders[:4]) + (", …" if len(folders) > 4 else "")
        _log.warning(
            "warning: %s is read as one episode whose views are its folders %s; if each folder is an "
            "episode of one camera instead, name its images <camera>_<n>.png (front_000123.png): such "
            "folders are read as episodes of view <camera>",
            root,
            shown,
        )
    return [trajectory], []


LAYOUT: Final = register(
    Layout(
        name="episode",
        detect=_detect,
        read=_read,
        help="one episode: <dir>/{<view>}/<n>.png, <dir>/<view>_<n>.png, <dir>/<n>.png or <dir>/<view>.mp4",
        listed=6,
        detect_order=110,  # last: one episode folder, what any folder of images is
        names_symbols=True,
    )
)
