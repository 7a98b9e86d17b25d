"""Folders of image episodes with any names: `<root>/<episode>/<view>/<n>.<png|jpg>` or `<root>/<episode>/<view>_<n>.<png|jpg>`.

Tried after the named layouts (AHA, ManiSkill), before one episode folder. A folder of
`<view>_<n>` images is an episode when it holds two views or more, or when it holds one view whose
name is neither the folder's nor a word for a frame (`frame`, `img`, `image`: `folders.FRAME_WORDS`)
and the root holds two such folders or more (`runs/run_0/front_0.png`, `runs/run_1/front_0.png`:
episodes of one camera, view `front`). A root whose folders hold images named by a number alone (`run_0/000123.png`) or by
a frame word (`frame_000123.png`) is ambiguous — views of one episode (`ep/front/000123.png`) look
the same — and is left to one episode folder (docs/data.md, "Folders of image episodes"). The task:
`--task`, else the `task` column of the labels file, else an AHA-style episode name; outcome and
symbol from that name or `--labels`. Trajectories are keyed by the episode folder's name.
"""

from __future__ import annotations

from pathlib import Path
from typing import Final

from robofailring.data.grounding import Vocabulary
from robofailring.data.layouts.aha import parse_aha_name
from robofailring.data.layouts.folders import (
    FRAME_WORDS,
    Views,
    aha_files,
    beside,
    is_image,
    listing,
    looped,
    subdirs,
    unread,
    view_folders,
)
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.model import Outcome, Skipped, Trajectory
from robofailring.progress import progress_bar

SHAPE: Final[str] = (
    "image episodes <root>/<episode>/<view>/<n>.png or <root>/<episode>/<view>_<n>.png (one view: two such "
    "episode folders or more)"
)


def flat_episode(directory: Path) -> bool:
    """A folder of `<view>_<n>` images of two views or more (read as one view folder, its numbers clash)."""
    return len(aha_files(directory)[0]) >= 2


def _one_camera(views: Views, directory: Path) -> bool:
    """`views` (a folder's `<view>_<n>` images) are one camera's: one view, named neither by a frame word
    nor by the folder's own name (a view folder `front/front_0.png`)."""
    camera = next(iter(views)) if len(views) == 1 else None
    return (
        camera is not None and camera.lower() not in FRAME_WORDS and camera.lower() != directory.name.lower()
    )


def one_view_episode(directory: Path) -> bool:
    """A folder of one camera's `<view>_<n>` images, `<view>` naming a camera: neither the folder's own
    name (a view folder `front/front_0.png`) nor a frame word (`front/frame_0.png`)."""
    return _one_camera(aha_files(directory)[0], directory)


def nested_episode(directory: Path) -> bool:
    """A folder of view sub-folders of numbered images."""
    return bool(subdirs(directory)) and bool(view_folders(directory)[0])


def _episode_views(directory: Path) -> tuple[Views, list[Skipped]] | None:
    """The views of an episode folder and what in it is not read, listing it once (no stat per file);
    None: no episode."""
    listed = listing(directory)
    views, skipped = aha_files(directory, listed)
    if len(views) >= 2 or _one_camera(views, directory):
        kind = "an episode of images named <view>_<n>"
        others = [entry[0] for entry in listed if not is_image(entry)]
    else:
        if not subdirs(directory):
            return None
        views, skipped = view_folders(directory)
        if not views:
            return None
        kind, others = "an episode of view folders", [p for p, is_file in listed if is_file or looped(p)]
    return views, skipped + [unread(p, f"not part of {kind}") for p in others]


def image_trajectories(root: Path, *, task: str | None = None, vocabulary: Vocabulary | None = None) -> Found:
    """One trajectory per episode folder; folders that hold no episode are listed as skipped."""
    found: list[Trajectory] = []
    skipped = beside(root, "a file beside the episode folders")
    folders = subdirs(root)
    with progress_bar(total=len(folders), desc=f"listing {root.name or root}", unit="episode") as bar:
        for directory in folders:
            bar.update(1)
            read = _episode_views(directory)
            if read is None:
                skipped.append(Skipped(directory, f"not an episode folder ({SHAPE})"))
                continue
            views, inside = read
            parsed = parse_aha_name(directory.name, vocabulary)
            symbol = parsed[1] if parsed is not None else None
            found.append(
                Trajectory(  # task "": from the labels' task column
                    task=task or (parsed[0] if parsed is not None else ""),
                    episode=directory.name,
                    views=views,
                    symbol=symbol,
                    outcome=(Outcome.FAILURE if symbol else Outcome.SUCCESS) if parsed is not None else None,
                    source=directory,
                    skipped=tuple(inside),
                )
            )
    return found, skipped


def _detect(root: Path) -> bool:
    folders = subdirs(root)
    return any(flat_episode(d) or nested_episode(d) for d in folders) or (
        sum(map(one_view_episode, folders)) >= 2
    )


LAYOUT: Final = register(
    Layout(
        name="images",
        detect=_detect,
        read=image_trajectories,
        help=SHAPE,
        listed=7,
        detect_order=100,  # after the named layouts (AHA, ManiSkill), before one episode folder, which it would otherwise be read as
        names_symbols=True,
    )
)
