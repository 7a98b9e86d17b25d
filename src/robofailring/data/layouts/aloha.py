"""ALOHA / ACT episodes: a folder of `episode_<i>.hdf5`, each `/observations/images/<cam>` (+ qpos, action).

`/observations/qpos`, `qvel`, `effort` (state) and `/action` are the episode's signals, their 14
dimensions named by ALOHA's joints (`left_waist` … `right_gripper`).

A camera is raw (N, H, W, 3) uint8, or, when the file's `compress` attribute is true, (N, L) uint8
rows each holding one JPEG padded with zeros; either is read a row at a time. ALOHA's
`record_episodes.py` JPEG-encodes the camera's RGB array as it is (`cv2.imencode`) and ACT reads it
back with `cv2.imdecode` and no swap, so a row decodes to RGB without a channel swap. Each camera is a view;
trajectories are keyed by the file's stem (`episode_3`); the task is `--task`, else the folder's
name; outcome and symbol come from `--labels`.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Final

from robofailring.data.hdf5 import (
    HDF5Frames,
    describe,
    hdf5_faults,
    is_hdf5,
    is_image_array,
    is_jpeg_rows,
    open_hdf5,
    row_format,
)
from robofailring.data.layouts.folders import visible
from robofailring.data.layouts.hdf5_signals import aloha_signals
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.model import Frame, Skipped, Trajectory
from robofailring.errors import DataError

_EPISODE: Final = re.compile(r"^episode_\d+$")
SHAPE: Final[str] = "episode_<i>.hdf5 with /observations/images/<cam> (N, H, W, 3) uint8 or JPEG rows"


def aloha_episode(path: Path, *, task: str) -> Trajectory:
    """One ALOHA episode file; another structure is an error listing what the file holds."""
    handle = open_hdf5(path)
    images = handle.get("observations/images")
    if images is None or not hasattr(images, "keys"):
        raise DataError(f"HDF5 file {path} is not an ALOHA episode ({SHAPE}); it holds: {describe(handle)}")
    compressed = bool(handle.attrs.get("compress", False))
    views: dict[str, Sequence[Frame]] = {}
    for cam in images:
        item, dataset = images[cam], f"/observations/images/{cam}"
        if is_image_array(item) or (compressed and is_jpeg_rows(item)):
            views[cam] = HDF5Frames(path, dataset, int(item.shape[0]), form=row_format(handle, dataset))
        else:
            raise DataError(
                f"{path}: camera {cam!r} is {tuple(item.shape)} {item.dtype}: neither (N, H, W, 3) uint8 nor "
                f"JPEG rows under the file attribute compress=True; it holds: {describe(handle)}"
            )
    if not views:
        raise DataError(
            f"HDF5 file {path} has no camera under /observations/images; it holds: {describe(handle)}"
        )
    return Trajectory(
        task=task, episode=path.stem, views=views, source=path, signals=aloha_signals(path, handle)
    )


def aloha_trajectories(root: Path, *, task: str | None = None) -> Found:
    """The episode files of a folder (or one episode file); other files are listed as skipped."""
    if root.is_file():
        with hdf5_faults(root):
            return [aloha_episode(root, task=task or root.parent.name)], []
    found: list[Trajectory] = []
    skipped: list[Skipped] = []
    for path in visible(root):
        if is_hdf5(path) and _EPISODE.match(path.stem):
            with hdf5_faults(path):
                found.append(aloha_episode(path, task=task or root.name))
        else:
            skipped.append(Skipped(path, f"not an ALOHA episode file ({SHAPE})"))
    return found, skipped


def _detect(root: Path) -> bool:
    if root.is_file():
        with hdf5_faults(root):
            return is_hdf5(root) and "observations" in open_hdf5(root)
    return any(is_hdf5(p) and _EPISODE.match(p.stem) for p in root.iterdir())


LAYOUT: Final = register(
    Layout(
        name="aloha",
        detect=_detect,
        read=aloha_trajectories,
        help=f"ALOHA/ACT episodes <root>/{SHAPE}",
        listed=9,
        detect_order=30,  # HDF5 episodes of a shape no other layout has
        reads_files=True,
    )
)
