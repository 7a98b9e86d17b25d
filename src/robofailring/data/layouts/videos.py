"""Video episodes: `<root>/<episode>/<view>.mp4|.webm|.mkv`, one trajectory per folder of videos.

The task: `--task`, else the `task` column of the labels file, else an AHA-style episode name
(`load_dataset` names the episodes none of them tells); outcome and symbol from that name or `--labels`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Final

from robofailring.data.grounding import Vocabulary
from robofailring.data.layouts.episode import episode_trajectory
from robofailring.data.layouts.folders import beside, has_images, has_videos, subdirs
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.model import Skipped, Trajectory
from robofailring.errors import DataError


def video_trajectories(root: Path, *, task: str | None = None, vocabulary: Vocabulary | None = None) -> Found:
    """`<root>/<episode>/<view>.mp4`: one trajectory per folder of videos; others reported."""
    found: list[Trajectory] = []
    skipped = beside(root, "a file beside the episode folders")
    for directory in subdirs(root):
        if not has_videos(directory):
            skipped.append(Skipped(directory, "no video file (.mp4, .webm, .mkv) in this episode folder"))
            continue
        try:  # task "": from the labels' task column, else an error of load_dataset naming the episodes
            found.append(
                episode_trajectory(directory, task=task if task is not None else "", vocabulary=vocabulary)
            )
        except DataError as error:
            skipped.append(Skipped(directory, str(error)))
    return found, skipped


def _detect(root: Path) -> bool:
    """Folders of videos and none of images (a folder of images is an episode of another layout)."""
    folders = subdirs(root)
    return any(has_videos(sub) for sub in folders) and not any(has_images(sub) for sub in folders)


LAYOUT: Final = register(
    Layout(
        name="videos",
        detect=_detect,
        read=video_trajectories,
        help="video episodes <root>/<episode>/<view>.mp4|.webm|.mkv",
        names_symbols=True,
        listed=5,
        detect_order=70,  # before the image layouts: a folder of video episodes
    )
)
