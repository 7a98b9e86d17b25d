"""A dataset root opened: its layout detected (the registered layouts tried in their order), read, labelled and its
views picked (docs/data.md, "Data layouts read")."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from robofailring.data.grounding import Vocabulary
from robofailring.data.hdf5 import is_hdf5, unreadable
from robofailring.data.labels import apply_labels, read_labels, unlabelled_rows
from robofailring.data.layouts.episode import episode_trajectory
from robofailring.data.layouts.folders import visible
from robofailring.data.layouts.project import (
    PROJECT_MANIFEST,
    project_trajectories,
    read_project_manifest,
)
from robofailring.data.layouts.registry import Layout, in_detection_order, layouts_help
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.views import select_views
from robofailring.errors import DataError, reading


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
    labelled: bool = False  # some outcomes come from the data itself (its names) or from a labels file

    @property
    def views(self) -> list[str]:
        """The views read (after `--views`), in the order they first appear."""
        return list(dict.fromkeys(view for trajectory in self.episodes for view in trajectory.views))

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

    def judged(self, what: str) -> tuple[list[Trajectory], list[Skipped]]:
        """For `what`, a verb that needs outcomes: the trajectories that have one, and what was not used.

        One rule for every layout: a run is a success or a failure only when its name or a labels
        file says so; a dataset that says it of none is an error (`require_labels`), and runs left
        without an outcome beside labelled ones are never taken for successes: they are listed with
        `skipped` as not used.
        """
        self.require_labels(what)
        judged = [t for t in self.episodes if t.outcome is not None]
        unlabelled = [t.key for t in self.episodes if t.outcome is None]
        if not unlabelled:
            return judged, self.skipped
        shown = ", ".join(unlabelled[:3]) + (" …" if len(unlabelled) > 3 else "")
        note = Skipped(
            self.root,
            f"{len(unlabelled)} episode(s) without an outcome (neither their name nor the labels file says "
            f"success or failure: {shown}): not used by {what}",
        )
        return judged, [*self.skipped, note]

    def select(self, *, split: str | None = None, keys: Sequence[str] | None = None) -> list[Trajectory]:
        """Trajectories of a split and/or with given keys (`<task>/<episode>` or the episode alone)."""
        chosen = [t for t in self.trajectories() if split is None or t.split == split]
        return _with_keys(chosen, keys, where=f"{self.root} ({self.layout} layout)")


def _with_keys(
    trajectories: Sequence[Trajectory],
    keys: Sequence[str] | None,
    *,
    where: str,
    unread: Sequence[Skipped] = (),
) -> list[Trajectory]:
    """The trajectories with given keys (`<task>/<episode>` or the episode alone); all when `keys` is empty.

    A key naming an entry the layout did not read (`unread`: a bag with no camera topic) says why."""
    if not keys:
        return list(trajectories)
    chosen = [t for t in trajectories if t.key in keys or t.episode in keys]
    found = {t.key for t in chosen} | {t.episode for t in chosen}
    missing = [k for k in keys if k not in found]
    if missing:
        why = next((s for s in unread if missing[0] in (s.path.name, s.path.stem)), None)
        raise DataError(
            f"no trajectory {missing[0]!r} in {where}"
            + (f"; {why.path}: {why.reason}" if why is not None else "")
        )
    return chosen


def _layout(root: Path) -> Layout:
    root = Path(root)
    layouts = in_detection_order()
    if root.is_file():
        for layout in layouts:
            if layout.reads_files and layout.detect(root):
                return layout
        readers = ", ".join(layout.name for layout in layouts if layout.reads_files)
        raise DataError(
            f"dataset root {root} is a file of no layout read from one file ({readers}); {layouts_help()}"
        )
    if not root.is_dir():
        raise DataError(f"dataset root {root} is not a directory")
    for layout in layouts:
        if layout.detect(root):
            return layout
    damaged = [why for path in visible(root) if is_hdf5(path) and (why := unreadable(path)) is not None]
    if damaged:  # its HDF5 files may well be a layout's: say why they were not read
        more = (
            f"; {len(damaged) - 1} more HDF5 file(s) in it cannot be read either" if len(damaged) > 1 else ""
        )
        raise DataError(f"{root} matches no known dataset layout: {damaged[0]}{more}")
    raise DataError(f"{root} matches no known dataset layout; {layouts_help()}")


def _finish(
    trajectories: list[Trajectory], *, layout: str, root: Path, views: str | None
) -> list[Trajectory]:
    """Every trajectory with its layout and the views `--views` picks; one without a task is an error."""
    untold = [t.episode for t in trajectories if not t.task]
    if untold:
        raise DataError(
            f"cannot tell the task of {len(untold)} episode(s) of {root} ({layout} layout), e.g. {untold[0]!r}: "
            "pass --task, or a task column in the --labels file"
        )
    chosen = select_views(trajectories, views, where=f"{root} ({layout} layout)")
    return [replace(t, layout=layout) for t in chosen]


def detect_layout(root: Path) -> str:
    """The layout name of a dataset root, or DataError naming the layouts expected."""
    return _layout(root).name


@reading()  # a folder or file this user may not read: status 1, naming it
def load_dataset(
    root: Path,
    *,
    task: str | None = None,
    labels: Path | None = None,
    views: str | None = None,
    vocabulary: Vocabulary | None = None,
    keys: Sequence[str] | None = None,
) -> Dataset:
    """Open a dataset root of any supported layout (auto-detected), listing what it does not read.

    `task` names the task of episodes whose names do not say it (one episode, video episodes);
    `labels` is a labels file (see `robofailring.data.labels`) giving outcome, symbol and task per
    episode, its symbols checked against Table 5 and `vocabulary` (the dataset's own symbols); `keys`
    keeps only the trajectories named (`<task>/<episode>` or the episode: `--trajectory`), chosen
    before `views` (`a,b` or `src=name,…`, see `robofailring.data.views`) picks and names their views.
    """
    root = Path(root)
    layout = _layout(root)
    manifest = layout.manifest(root) if layout.manifest is not None else None
    named = {"vocabulary": vocabulary} if layout.names_symbols else {}  # its names may use the dataset's own
    found, skipped = layout.read(root, task=task, **named)
    if labels is not None:
        found = apply_labels(found, read_labels(labels, vocabulary=vocabulary), source=Path(labels))
        blank = unlabelled_rows(Path(labels))
        skipped = [*skipped, *([blank] if blank is not None else [])]
    labelled = labels is not None or any(t.outcome is not None for t in found)
    found = _with_keys(found, keys, where=f"{root} ({layout.name} layout)", unread=skipped)
    return Dataset(
        root=root,
        layout=layout.name,
        episodes=tuple(_finish(found, layout=layout.name, root=root, views=views)),
        unread=tuple(skipped),
        manifest=manifest,
        labelled=labelled,
    )


@reading()
def load_trajectory(
    path: Path,
    *,
    task: str | None = None,
    key: str | None = None,
    labels: Path | None = None,
    views: str | None = None,
    vocabulary: Vocabulary | None = None,
) -> Trajectory:
    """One trajectory from an episode folder of any layout, or the one named `key` in a dataset root.

    The task comes from the folder name where the layout encodes it, else from `task`; `views` as
    in `load_dataset`.
    """
    path = Path(path)
    if not path.is_dir() and not path.is_file():
        raise DataError(f"trajectory {path} is not a directory")
    if (
        path.is_file()
        or key is not None
        or (path / PROJECT_MANIFEST).is_file()
        or detect_layout(path) != "episode"
    ):
        dataset = load_dataset(
            path,
            task=task,
            labels=labels,
            views=views,
            vocabulary=vocabulary,
            keys=[key] if key is not None else None,
        )
        found = list(dataset.trajectories())
        if len(found) != 1:
            raise DataError(
                f"{path} is a {dataset.layout} dataset with {len(found)} trajectories; pass one of its episode "
                "folders, choose one with --trajectory (e.g. --trajectory "
                f"{found[0].episode if found else 'EPISODE'}), or replay the whole dataset with `robofailring replay`"
            )
        return found[0]
    parent_manifest = path.parent / PROJECT_MANIFEST
    if parent_manifest.is_file():
        for trajectory in project_trajectories(path.parent, read_project_manifest(path.parent))[0]:
            if trajectory.source is not None and trajectory.source.resolve() == path.resolve():
                return _finish([trajectory], layout="project", root=path, views=views)[0]
    trajectory = episode_trajectory(path, task=task, vocabulary=vocabulary)
    return _finish([trajectory], layout="episode", root=path, views=views)[0]
