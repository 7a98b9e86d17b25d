"""Episode folders of images or videos: the views of one episode, whatever layout holds it.

Every function here returns what it read *and* what it did not read (`Skipped`, with the reason):
nothing under a dataset root is dropped silently. Hidden names (starting with `.`) are ignored.
A frame's number is the last number in its name, a decimal part included (`1700000000.800000.png`,
a timestamp, is frame 1700000000.8, not 800000); images named by a number alone directly in an
episode folder are the view `image`. A view whose first frame is a 16-bit PNG (a depth camera) is
not read as colour: it is listed as not read.
"""

from __future__ import annotations

import errno
import os
import re
from collections.abc import Sequence
from decimal import Decimal
from pathlib import Path
from typing import Final

from robofailring.data.images import IMAGE_SUFFIXES, png_bit_depth
from robofailring.data.model import Frame, FrameFiles, Skipped
from robofailring.data.video import VIDEO_SUFFIXES, VideoFrames, open_video
from robofailring.errors import DataError

_NUMBER = r"\d+(?:\.\d+)?"
_AHA_FRAME = re.compile(rf"^(?P<view>.+)_(?P<idx>{_NUMBER})$")
_BARE_FRAME = re.compile(rf"^(?P<idx>{_NUMBER})$")
_LAST_NUMBER = re.compile(rf"({_NUMBER})(?!.*\d)")
#: The view of images named by a number alone (`000123.png`) directly in an episode folder.
BARE_VIEW: Final[str] = "image"
#: File-name words for a frame, not a camera: `frame_000123.png` names no view.
FRAME_WORDS: Final[frozenset[str]] = frozenset({BARE_VIEW, "frame", "frames", "img", "im"})

Views = dict[str, Sequence[Frame]]  # view name -> its frames in order


def visible(directory: Path) -> list[Path]:
    """The entries of a folder in natural order, hidden names left out."""
    return sorted((p for p in directory.iterdir() if not p.name.startswith(".")), key=natural_key)


def natural_key(path: Path) -> list[tuple[int, int | str]]:
    """`episode2` before `episode10`, `seed 3` before `seed 10`; names otherwise alphabetical."""
    return [(0, int(part)) if part.isdecimal() else (1, part) for part in re.split(r"(\d+)", path.name)]


def subdirs(directory: Path) -> list[Path]:
    """The sub-folders of a folder in natural order, hidden ones and symlink loops (`looped`) left out
    (one listing: a folder of 600 frames is not stat-ed file by file)."""
    with os.scandir(directory) as entries:
        found = [
            Path(e.path)
            for e in entries
            if not e.name.startswith(".") and _is(e, "dir") and not (e.is_symlink() and looped(Path(e.path)))
        ]
    return sorted(found, key=natural_key)


def _is(entry: os.DirEntry[str], kind: str) -> bool:
    """Whether a folder entry is a `dir` or a `file`; False for a link that loops (ELOOP), which `looped` names."""
    try:
        return entry.is_dir() if kind == "dir" else entry.is_file()
    except OSError:
        return False


def looped(path: Path) -> str | None:
    """Why a symlink is not followed: it leads back to a folder holding it (`front/again -> .`), so walking
    it never ends, or it loops without reaching anything; None for any other path."""
    if not path.is_symlink():
        return None
    try:
        target = path.resolve(strict=True)
    except RuntimeError:  # Python 3.11 says "Symlink loop from …"
        return f"a symlink loop ({path} -> {os.readlink(path)} never reaches a file or folder): not read"
    except OSError as error:
        if error.errno != errno.ELOOP:
            return None  # a dangling link: listed by its caller as what it is not
        return f"a symlink loop ({path} -> {os.readlink(path)} never reaches a file or folder): not read"
    holder = path.parent.resolve()
    if target == holder or target in holder.parents:
        return f"a link back to {target}, a folder holding it (a symlink loop): not read"
    return None


def unread(path: Path, reason: str) -> Skipped:
    """`path` listed as not read, for `reason`, or as the symlink loop it is (`looped`)."""
    return Skipped(path, looped(path) or reason)


def beside(directory: Path, reason: str) -> list[Skipped]:
    """A folder of folders' files (beside its episodes or tasks), each listed as not read for `reason`, and
    its symlink loops (`looped`), which `subdirs` leaves out, for theirs."""
    return [unread(p, reason) for p in visible(directory) if p.is_file() or looped(p)]


def listing(directory: Path) -> list[tuple[Path, bool]]:
    """The entries of a folder in natural order, hidden names left out, each with whether it is a file:
    one scandir, whose entries carry their type, so a folder of 600 frames is not stat-ed file by file."""
    with os.scandir(directory) as entries:
        found = [(Path(e.path), _is(e, "file")) for e in entries if not e.name.startswith(".")]
    return sorted(found, key=lambda entry: natural_key(entry[0]))


def is_image(entry: tuple[Path, bool]) -> bool:
    """A `listing` entry that is an image file (by its suffix)."""
    path, is_file = entry
    return is_file and path.suffix.lower() in IMAGE_SUFFIXES


def frame_number(stem: str) -> Decimal | None:
    """A frame's number: the last number in its name, a decimal part included (exact); None when none."""
    match = _LAST_NUMBER.search(stem)
    return Decimal(match.group(1)) if match else None


def _numbered(paths: Sequence[tuple[Path, Decimal]], where: Path, *, view: str) -> Sequence[Frame]:
    """The frames of files in folder `where`, ordered by number, held compactly (`FrameFiles`); two files
    with one number are an error naming both."""
    seen: dict[Decimal, Path] = {}
    for path, number in paths:
        if number in seen:
            raise DataError(
                f"two frames numbered {number} in view {view!r} of {where}: {seen[number].name} and {path.name}; "
                "rename or remove one (which one is frame "
                f"{number} cannot be decided)"
            )
        seen[number] = path
    return FrameFiles(where, [seen[number].name for number in sorted(seen)])


def _unnumbered(where: Path, names: list[str], pattern: str) -> Skipped:
    shown = ", ".join(names[:3]) + (", …" if len(names) > 3 else "")
    return Skipped(
        where, f"{len(names)} image(s) without a frame number ({shown}); frames are named {pattern}"
    )


def _colour(views: Views, skipped: list[Skipped]) -> tuple[Views, list[Skipped]]:
    """The views whose first frame is not a 16-bit PNG; the others listed as not read."""
    colour: Views = {}
    for view, frames in views.items():
        first = frames[0].path if frames else None
        depth = png_bit_depth(first) if first is not None else None
        if first is not None and depth is not None and depth > 8:
            skipped.append(
                Skipped(
                    first.parent,
                    f"view {view!r}: {depth}-bit PNG images (a depth camera?), not 8-bit colour: not read",
                    view=view,
                )
            )
        else:
            colour[view] = frames
    return colour, skipped


def aha_files(
    directory: Path, listed: Sequence[tuple[Path, bool]] | None = None
) -> tuple[Views, list[Skipped]]:
    """Frames of an episode folder of `<view>_<idx>.png` files (a number alone: view `image`), by view
    (`listed`: the folder's `listing`, when the caller has it)."""
    grouped: dict[str, list[tuple[Path, Decimal]]] = {}
    unnumbered: list[str] = []
    for entry in listing(directory) if listed is None else listed:
        if not is_image(entry):
            continue
        path = entry[0]
        match = _AHA_FRAME.match(path.stem) or _BARE_FRAME.match(path.stem)
        if match:
            view = match.groupdict().get("view") or BARE_VIEW
            grouped.setdefault(view, []).append((path, Decimal(match["idx"])))
        else:
            unnumbered.append(path.name)
    views: Views = {view: _numbered(paths, directory, view=view) for view, paths in sorted(grouped.items())}
    skipped = [_unnumbered(directory, unnumbered, "<view>_<index>.<ext>")] if unnumbered else []
    return _colour(views, skipped)


def camera_named(directory: Path) -> str | None:
    """The one camera a folder's `<view>_<n>` images name, or None: several, none, or a frame word
    (`frame_000123.png`, `000123.png`), where only the folder's own name could say what it holds."""
    views = aha_files(directory)[0]
    view = next(iter(views)) if len(views) == 1 else None
    return None if view is None or view.lower() in FRAME_WORDS else view


def view_folders(directory: Path) -> tuple[Views, list[Skipped]]:
    """Frames of an episode stored as one sub-folder of numbered images per view."""
    views: Views = {}
    skipped: list[Skipped] = []
    for sub in subdirs(directory):
        numbered: list[tuple[Path, Decimal]] = []
        unnumbered: list[str] = []
        others: list[str] = []
        for entry in listing(sub):
            path = entry[0]
            if is_image(entry):
                number = frame_number(path.stem)
                if number is not None:
                    numbered.append((path, number))
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
                unread(sub / name, "not an image (.png, .jpg, .jpeg, .bmp, .webp)") for name in others
            ]
        elif not numbered and not unnumbered:
            skipped.append(Skipped(sub, "no images in this view folder"))
    return _colour(views, skipped)


def video_views(directory: Path) -> Views:
    """One view per video file of the folder (`<view>.mp4|.webm|.mkv`), decoded lazily."""
    return {
        path.stem: VideoFrames(open_video(path))
        for path in visible(directory)
        if path.is_file() and path.suffix.lower() in VIDEO_SUFFIXES
    }


def episode_views(directory: Path) -> tuple[Views, list[Skipped]]:
    """Views of an episode folder: `<view>_<idx>` images, else view sub-folders, else `<view>.mp4` videos.

    Whatever else the folder holds is returned as skipped, with the reason.
    """
    entries = listing(directory)
    views, skipped = aha_files(directory, entries)
    if views or skipped:
        kind, others = "images named <view>_<index>", [entry[0] for entry in entries if not is_image(entry)]
    else:
        views, skipped = view_folders(directory)
        folders = set(subdirs(directory))
        kind, others = "view folders", [p for p, _ in entries if p not in folders]
        if not views:
            views, skipped = video_views(directory), []
            kind = "videos"
            others = [p for p, is_file in entries if not (is_file and p.suffix.lower() in VIDEO_SUFFIXES)]
    if views:
        skipped += [unread(p, f"not part of an episode stored as {kind}") for p in others]
    return views, skipped


def has_videos(directory: Path) -> bool:
    return any(p.suffix.lower() in VIDEO_SUFFIXES and p.is_file() for p in directory.iterdir())


def has_images(directory: Path) -> bool:
    return any(p.suffix.lower() in IMAGE_SUFFIXES and p.is_file() for p in directory.iterdir())
