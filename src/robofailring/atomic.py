"""Atomic writes (public: the library and rfr_viz both use them): everything is written under a temporary name and renamed into place.

Temporary names are `.<final name>.rfr-<8 random characters>.tmp[suffix]` beside the final path; a
replaced folder is moved aside as `.<final name>.rfr-<8 characters>.old` until its successor is in
place. A process killed half-way leaves only such names; `output_lock` finds them on the next
write to the same path and removes them, or restores an `.old` folder whose successor never
arrived. The `rfr-` mark keeps that cleaning to this module's own names: a user's
`.<name>.<anything>.tmp` beside an output is never touched. A temporary file is held under an
exclusive `flock` by the process writing it, for as long as it writes (a `watch --save` for hours):
cleaning removes only a file no live process holds, whatever lock that writer took on its output
(docs/errors.md, "When things go wrong").

A final path that is a symbolic link is written where it points: the link stays a link to the new
version (replacing the link itself would leave the old version at its target, still in use).
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from robofailring.errors import OutputBusyError

_log = logging.getLogger("robofailring")
_HELD: dict[Path, int] = {}  # lock files this process holds, with their nesting depth
_MARK = "rfr-"  # in every temporary name this module makes, and only in those


def _target(final: Path) -> Path:
    """Where a write to `final` goes: `final`, or where it points when it is a symbolic link."""
    final = Path(final).absolute()
    return Path(os.path.realpath(final)) if final.is_symlink() else final


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(final: Path, *, suffix: str = "", claim: bool = False) -> Iterator[Path]:
    """Yield a temporary file path beside `final`; rename it onto `final` only if the block succeeds.

    With `claim` (a job's output: a recording, a table) `final`'s `output_lock` is held while it is
    written, so a second writer stops (OutputBusyError), and a version another process put at `final`
    meanwhile is never replaced: this one is kept beside it under a free name, and OutputBusyError
    says where (nothing lost either way)."""
    final = _target(final)
    with contextlib.ExitStack() as stack:
        if claim:
            stack.enter_context(output_lock(final))
        before = _version(final)
        final.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = _held_temporary(final, suffix)
        try:
            yield tmp
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; the result is shared like any file
            if claim and _version(final) != before:
                raise OutputBusyError(
                    f"another process wrote {final} while this one was writing it; it is left as it is, "
                    f"and this output is kept as {_keep_beside(tmp, final)}"
                )
            os.replace(tmp, final)
        finally:
            try:
                if tmp.exists():
                    tmp.unlink()
            finally:
                os.close(fd)  # releases the flock: from here the name is gone or is `final`


def _version(path: Path) -> tuple[int, int, int] | None:
    """Which version of a file is at `path` (inode, size, modification time); None when there is none."""
    try:
        stat = os.stat(path)
    except FileNotFoundError:
        return None
    return stat.st_ino, stat.st_size, stat.st_mtime_ns


def _keep_beside(tmp: Path, final: Path) -> Path:
    """`tmp` linked under the first free name `<stem>-<n><suffix>` beside `final` (never over a file)."""
    number = 2
    while True:
        kept = final.with_name(f"{final.stem}-{number}{final.suffix}")
        try:
            os.link(tmp, kept)
        except FileExistsError:
            number += 1
            continue
        return kept


def _held_temporary(final: Path, suffix: str) -> tuple[int, Path]:
    """A new temporary file beside `final` and an open descriptor holding its exclusive flock.

    Another process's cleaning may take a file in the moment between its creation and the lock (it
    then unlinks it): the lock is only kept on a file still under its name, else a new one is made."""
    while True:
        fd, name = tempfile.mkstemp(prefix=f".{final.name}.{_MARK}", suffix=f".tmp{suffix}", dir=final.parent)
        fcntl.flock(fd, fcntl.LOCK_EX)
        with contextlib.suppress(FileNotFoundError):
            if os.stat(name).st_ino == os.fstat(fd).st_ino:
                return fd, Path(name)
        os.close(fd)


def _remove_unheld(path: Path) -> None:
    """Remove a temporary file unless a live process holds it (`atomic_path`'s flock): a writer still
    at work, not a leftover."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:  # gone already, or not a plain file of ours
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return
    try:
        path.unlink(missing_ok=True)  # under the lock: a writer that locks it next sees it unlinked
    finally:
        os.close(fd)


def write_text_atomic(final: Path, text: str, *, claim: bool = False) -> None:
    """Write a text file atomically (`claim`: a job's output, see `atomic_path`)."""
    with atomic_path(final, claim=claim) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _leftover(final: Path, name: str) -> str | None:
    """'tmp' or 'old' when `name` is a leftover of a write to `final`, else None."""
    match = re.fullmatch(rf"\.{re.escape(final.name)}\.{_MARK}[A-Za-z0-9_]{{8}}\.(tmp|old)(\..+)?", name)
    return match[1] if match else None


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)  # a folder's writer holds `output_lock`, as its cleaner does
    elif path.is_file() and not path.is_symlink():
        _remove_unheld(path)
    else:
        path.unlink(missing_ok=True)


def recover_leftovers(final: Path) -> None:
    """Remove what killed writes to `final` left beside it; restore `final` from an `.old` if it is gone.

    Call only while holding `output_lock(final)`, so no live writer's files are touched.
    """
    final = _target(final)
    if not final.parent.is_dir():
        return
    found = [(entry, _leftover(final, entry.name)) for entry in final.parent.iterdir()]
    olds = sorted((entry for entry, kind in found if kind == "old"), key=lambda p: p.stat().st_mtime)
    for entry, kind in found:
        if kind == "tmp":
            _remove(entry)
    if olds and not final.exists():
        os.replace(olds.pop(), final)
        _log.warning(
            "restored %s: a replace of it was interrupted before the new version was in place", final
        )
    for old in olds:
        _remove(old)


def remove_file_leftovers(folder: Path) -> None:
    """Remove the temporary files killed writes left inside `folder` (hold `output_lock(folder)`); one
    that a live process is still writing (a `watch --save` into the folder) is left to it."""
    if Path(folder).is_dir():
        for entry in Path(folder).iterdir():
            if entry.is_file() and re.fullmatch(rf"\..+\.{_MARK}[A-Za-z0-9_]{{8}}\.tmp(\..+)?", entry.name):
                _remove_unheld(entry)


@contextlib.contextmanager
def output_lock(final: Path, *, wait: bool = False) -> Iterator[None]:
    """Hold `.<name>.lock` beside `final` while writing it; a second writer gets OutputBusyError, or with
    `wait` waits for the first to finish (a cache entry both would make alike: the second then finds it).

    On entry, the leftovers of killed writes to `final` are cleaned (see `recover_leftovers`).
    Re-entrant within one process. Folders made to hold the lock are removed again if nothing was
    written into them (a refused command leaves no empty folder).
    """
    final = _target(final)
    lock = final.parent / f".{final.name}.lock"
    if lock in _HELD:
        _HELD[lock] += 1
        try:
            yield
        finally:
            _HELD[lock] -= 1
        return
    made = [folder for folder in (final.parent, *final.parent.parents) if not folder.exists()]
    final.parent.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as stack:
        stack.callback(_remove_if_empty, made)
        stack.enter_context(_locked(lock, final, wait=wait))
        _HELD[lock] = 1
        try:
            recover_leftovers(final)
            yield
        finally:
            del _HELD[lock]
            lock.unlink(missing_ok=True)


def check_free(paths: Iterable[Path]) -> None:
    """OutputBusyError, before any work, when another process holds the `output_lock` of one of `paths`:
    for a job with more outputs than it could hold locks at once (each is claimed as it is written)."""
    for path in paths:
        with output_lock(path):
            pass


@contextlib.contextmanager
def _locked(lock: Path, final: Path, *, wait: bool) -> Iterator[None]:
    """`lock` opened and locked; the lock of a file its last holder removed meanwhile is taken anew."""
    while True:
        with lock.open("a") as handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise OutputBusyError(
                    f"another robofailring process is writing {final} right now; wait for it or choose another output"
                ) from None
            try:
                current = os.stat(lock).st_ino
            except FileNotFoundError:
                current = None
            if current == os.fstat(handle.fileno()).st_ino:  # still the file others open: ours
                yield
                return


def _remove_if_empty(folders: list[Path]) -> None:
    """Remove the folders (deepest first) that are still empty; any other is left as it is."""
    for folder in folders:
        with contextlib.suppress(OSError):
            folder.rmdir()


FolderState = tuple[tuple[str, int, int, int], ...]


def folder_state(folder: Path) -> FolderState:
    """One version of a folder written by this module: its own inode, and each visible file's inode,
    size and modification time. Replacing the folder (`atomic_directory`) or any file in it
    (`atomic_path`) changes it, so a writer can tell the folder it read from the one there now.
    Temporary and lock names (leading dot) are not part of it; an absent folder is `()`.
    """
    folder = Path(folder)
    try:
        own = folder.stat()
        files = sorted(entry for entry in folder.iterdir() if not entry.name.startswith("."))
        stats = [(entry.name, entry.stat()) for entry in files if entry.is_file()]
    except FileNotFoundError:  # replaced while being listed: a state no reader saw whole
        return ()
    return (("", own.st_ino, 0, 0), *((name, st.st_ino, st.st_size, st.st_mtime_ns) for name, st in stats))


def restore_interrupted(final: Path) -> bool:
    """Put back a folder whose replacement was killed half-way (its `.old` beside it); True if restored."""
    final = _target(final)
    if final.exists() or not final.parent.is_dir():
        return False
    if not any(_leftover(final, entry.name) == "old" for entry in final.parent.iterdir()):
        return False
    with output_lock(final):
        return final.exists()


def replace_directory(tmp: Path, final: Path) -> None:
    """Move the complete folder `tmp` onto `final`; the previous `final` stays recoverable until then."""
    if not final.exists():
        os.replace(tmp, final)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{final.name}.{_MARK}", suffix=".old", dir=final.parent))
    os.rmdir(old)
    os.replace(final, old)
    try:
        # killed here: `final` is absent, `old` holds the previous version and the next write or load restores it
        os.replace(tmp, final)
    except BaseException:
        os.replace(old, final)
        raise
    shutil.rmtree(old, ignore_errors=True)


@contextlib.contextmanager
def atomic_directory(final: Path) -> Iterator[Path]:
    """Yield a fresh temporary directory beside `final` and swap it into place on success.

    An existing directory at `final` is replaced only after the new one is complete, so an
    interrupted write leaves the previous version under the final name, or beside it as an
    `.old` folder that the next write or memory load restores.
    """
    final = _target(final)
    with output_lock(final):
        tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.{_MARK}", suffix=".tmp", dir=final.parent))
        try:
            yield tmp
            os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes 0700
            replace_directory(tmp, final)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
