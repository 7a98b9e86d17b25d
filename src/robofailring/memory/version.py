"""Which version of a memory's folder a memory was read from, so a write back over it never mixes two.

A command that reads a memory, works for a while and writes it back (`calibrate` its manifest,
`build-memory --add-to` the grown memory) must not write over a folder another process replaced
meanwhile: the manifest would then name entries the index does not hold. `read_whole` reads a folder
as one version (again when it changed mid-read) and returns that version; `refuse_stale`, called by
a writer holding the folder's `output_lock`, refuses (OutputBusyError, nothing written) when the
folder is no longer the version read.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from robofailring.atomic import FolderState, folder_state
from robofailring.errors import OutputBusyError

ReadFrom = tuple[Path, FolderState]  # the folder (resolved) and its version when read
T = TypeVar("T")


def read_whole(directory: Path, read: Callable[[Path], T], *, tries: int = 5) -> tuple[T, ReadFrom]:
    """`read(directory)` on one version of the folder, and that version; read again when another
    process replaced the folder while it was read (`tries` times, then OutputBusyError).

    Whatever a read raised while the folder changed under it (a file gone mid-swap, a header read
    from one version and a body from the next) is about a version that no longer exists, so it is
    read again; an error on a folder that stayed as it was is the folder's own and is raised.
    """
    directory = Path(directory)
    for attempt in range(tries):
        before = folder_state(directory)
        try:
            found = read(directory)
        except Exception as error:
            after = folder_state(directory)
            # the same version both times (or absent both times, and not a file vanishing mid-swap)
            if after == before and (before or not isinstance(error, OSError)):
                raise
            time.sleep(0.005 * (attempt + 1))  # let the other process finish its swap
            continue
        if before and folder_state(directory) == before:
            return found, (directory.resolve(), before)
    raise OutputBusyError(
        f"{directory} changed on each of {tries} reads: another robofailring process is writing it; "
        "try again when it is done"
    )


def refuse_stale(read_from: ReadFrom | None, directory: Path) -> None:
    """OutputBusyError when `read_from` is `directory`'s and the folder changed since (call holding
    `output_lock(directory)`: every writer of a memory holds it, so the check and the write after it
    see one version of the folder). A memory read from elsewhere, or never read, passes."""
    if read_from is None or read_from[0] != Path(directory).resolve():
        return
    if folder_state(directory) != read_from[1]:
        raise OutputBusyError(
            f"the memory at {directory} changed after this process read it (another robofailring "
            "process rebuilt, grew or calibrated it); nothing was written: run this command again "
            "on the memory as it is now"
        )


def require_read_from(read_from: ReadFrom | None, directory: Path) -> None:
    """OutputBusyError unless the memory was read from `directory` and the folder is still that version."""
    if read_from is None or read_from[0] != Path(directory).resolve():
        raise OutputBusyError(
            f"cannot rewrite the manifest of {directory}: this memory was not read from there"
        )
    refuse_stale(read_from, directory)
