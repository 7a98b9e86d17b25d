"""Dataset layouts (README, "Data layouts read"): AHA FailGen, ManiSkill-failgen/FailSafe, the project's own, one episode."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from robofailring.data.folders import (
    AHA_FAILURES,
    MANISKILL_FAILURE,
    MANISKILL_FAILURES,
    MANISKILL_SUCCESS,
    aha_files,
    aha_name_problem,
    aha_trajectories,
    episode_views,
    maniskill_trajectories,
    parse_aha_name,
    subdirs,
)
from robofailring.data.images import IMAGE_SUFFIXES
from robofailring.data.labels import apply_labels, read_labels
from robofailring.data.lerobot import is_lerobot, lerobot_trajectories
from robofailring.data.model import Outcome, Skipped, Trajectory
from robofailring.data.video import VIDEO_SUFFIXES
from robofailring.errors import DataError

__all__ = [
    "AHA_FAILURES",
    "LAYOUTS_HELP",
    "MANISKILL_FAILURES",
    "Dataset",
    "detect_layout",
    "load_dataset",
    "load_trajectory",
    "parse_aha_name",
]

PROJECT_MANIFEST: Final[str] = "manifest.json"
PROJECT_FORMAT: Final[str] = "robofailring-dataset"

LAYOUTS_HELP: Final[str] = (
    "expected one of: (1) the project's own layout (a manifest.json written by `robofailring generate`); "
    "(2) the AHA FailGen layout <root>/<task>_<failtype>_wp<k>_episode<e>/{front,overhead,wrist}_<idx>.png "
    "(or <task>_wrong_object[_wp<k>]_episode<e>); (3) the ManiSkill-failgen/FailSafe layout "
    "<root>/<task>/<seed>/{Ground_Truth | <ep>_<fail>_<stage>}/{front,side,wrist}/<n>.png; "
    "(4) a LeRobot dataset (v2.1 or v3.0: meta/info.json, parquet, one mp4 per camera); "
    "(5) video episodes <root>/<episode>/<view>.mp4|.webm|.mkv; "
    "(6) one episode: <dir>/{<view>}/<n>.png, <dir>/<view>_<n>.png or <dir>/<view>.mp4"
)


@dataclass(frozen=True)
class Dataset:
    """A dataset root, its layout, its trajectories (frames decoded on demand) and what was not read.

    `skipped` lists every folder or file under the root that no trajectory reads, with the reason.
    """

    root: Path
    layout: str
    episodes: tuple[Trajectory, ...] = ()
    unread: tuple[Skipped, ...] = field(default=(), repr=False)
    manifest: dict[str, Any] | None = None
    labelled: bool = False  # outcomes come from the data itself or from a labels file

    def __iter__(self) -> Iterator[Trajectory]:
        return self.trajectories()

    def trajectories(self) -> Iterator[Trajectory]:
        return iter(self.episodes)

    @property
    def skipped(self) -> list[Skipped]:
        """Folders and files not read: those beside the episodes, then those inside episodes."""
        return [*self.unread, *(s for t in self.episodes for s in t.skipped)]

    def require_labels(self, what: str) -> None:
        """A clear error when `what` needs outcomes this dataset does not have (LeRobot without labels)."""
        if not self.labelled:
            raise DataError(
                f"{what} needs to know which episodes failed, and the {self.layout} dataset {self.root} does not "
                "say: pass --labels FILE (a JSON list or CSV of episode_index, outcome, symbol)"
            )

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


def _has_videos(directory: Path) -> bool:
    return any(p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES for p in directory.iterdir())


def _has_images(directory: Path) -> bool:
    return any(p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES for p in directory.iterdir())


def detect_layout(root: Path) -> str:
    """The layout name of a dataset root, or DataError naming the layouts expected."""
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"dataset root {root} is not a directory")
    if (root / PROJECT_MANIFEST).is_file():
        return "project"
    if is_lerobot(root):
        return "lerobot"
    folders = subdirs(root)
    if any(_has_videos(sub) for sub in folders) and not any(_has_images(sub) for sub in folders):
        return "videos"
    if aha_trajectories(root, first_only=True)[0]:
        return "aha"
    if maniskill_trajectories(root, first_only=True)[0]:
        return "maniskill"
    if episode_views(root)[0]:
        return "episode"
    raise DataError(f"{root} matches no known dataset layout; {LAYOUTS_HELP}")


def load_dataset(root: Path, *, task: str | None = None, labels: Path | None = None) -> Dataset:
    """Open a dataset root of any supported layout (auto-detected), listing what it does not read.

    `task` names the task of episodes whose names do not say it (one episode, video episodes);
    `labels` is a labels file (see `robofailring.data.labels`) giving outcome and symbol per episode.
    """
    root = Path(root)
    layout = detect_layout(root)
    manifest = None
    skipped: list[Skipped] = []
    if layout == "project":
        manifest = read_project_manifest(root)
        found, skipped = _project_trajectories(root, manifest)
    elif layout == "lerobot":
        found, skipped = lerobot_trajectories(root)
    elif layout == "aha":
        found, skipped = aha_trajectories(root)
    elif layout == "maniskill":
        found, skipped = maniskill_trajectories(root)
    elif layout == "videos":
        found, skipped = _video_trajectories(root, task=task)
    else:
        found = [_episode_trajectory(root, task=task)]
    if labels is not None:
        found = apply_labels(found, read_labels(labels), source=Path(labels))
    return Dataset(
        root=root,
        layout=layout,
        episodes=tuple(found),
        unread=tuple(skipped),
        manifest=manifest,
        labelled=labels is not None or layout != "lerobot",
    )


def load_trajectory(
    path: Path, *, task: str | None = None, key: str | None = None, labels: Path | None = None
) -> Trajectory:
    """One trajectory from an episode folder of any layout, or the one named `key` in a dataset root.

    The task comes from the folder name where the layout encodes it, else from `task`.
    """
    path = Path(path)
    if not path.is_dir():
        raise DataError(f"trajectory {path} is not a directory")
    if key is not None or (path / PROJECT_MANIFEST).is_file() or detect_layout(path) != "episode":
        dataset = load_dataset(path, task=task, labels=labels)
        found = dataset.select(keys=[key]) if key is not None else list(dataset.trajectories())
        if len(found) != 1:
            raise DataError(
                f"{path} is a {dataset.layout} dataset with {len(found)} trajectories; pass one of its episode "
                "folders, choose one with --trajectory (e.g. --trajectory "
                f"{found[0].episode if found else 'EPISODE'}), or replay the whole dataset with `robofailring replay`"
            )
        return found[0]
    parent_manifest = path.parent / PROJECT_MANIFEST
    if parent_manifest.is_file():
        for trajectory in _project_trajectories(path.parent, read_project_manifest(path.parent))[0]:
            if trajectory.source is not None and trajectory.source.resolve() == path.resolve():
                return trajectory
    return _episode_trajectory(path, task=task)


def _episode_trajectory(path: Path, *, task: str | None) -> Trajectory:
    parsed = parse_aha_name(path.name)
    views, skipped = episode_views(path)
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
        problem = aha_name_problem(path.name)
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
    )


def _video_trajectories(root: Path, *, task: str | None) -> tuple[list[Trajectory], list[Skipped]]:
    """`<root>/<episode>/<view>.mp4`: one trajectory per folder of videos; others reported."""
    found: list[Trajectory] = []
    skipped: list[Skipped] = [
        Skipped(p, "a file beside the episode folders")
        for p in root.iterdir()
        if p.is_file() and not p.name.startswith(".")
    ]
    for directory in subdirs(root):
        if not _has_videos(directory):
            skipped.append(Skipped(directory, "no video file (.mp4, .webm, .mkv) in this episode folder"))
            continue
        try:
            found.append(_episode_trajectory(directory, task=task))
        except DataError as error:
            skipped.append(Skipped(directory, str(error)))
    return found, skipped


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


def _project_trajectories(root: Path, manifest: dict[str, Any]) -> tuple[list[Trajectory], list[Skipped]]:
    found = []
    listed = set()
    for record in manifest["episodes"]:
        try:
            directory = root / record["dir"]
            outcome = Outcome(record["outcome"])
            task = record["task"]
        except (KeyError, ValueError) as error:
            raise DataError(f"{root / PROJECT_MANIFEST}: bad episode record {record!r} ({error})") from error
        if not directory.is_dir():
            raise DataError(f"{root / PROJECT_MANIFEST} lists {record['dir']} but {directory} is missing")
        listed.add(Path(record["dir"]).parts[0])
        views, inside = aha_files(directory)
        wanted = record.get("views")
        if wanted:
            views = {view: views.get(view, ()) for view in wanted}
        found.append(
            Trajectory(
                task=task,
                episode=record.get("episode", record["dir"]),
                views=views,
                symbol=record.get("label"),
                outcome=outcome,
                source=directory,
                fps=record.get("fps", manifest.get("fps")),
                split=record.get("split"),
                skipped=tuple(inside),
            )
        )
    unlisted = [
        Skipped(p, f"not listed in {PROJECT_MANIFEST}")
        for p in sorted(root.iterdir())
        if p.name not in listed and p.name != PROJECT_MANIFEST and not p.name.startswith(".")
    ]
    return found, unlisted
