"""Image references of a memory that resolve from any working directory, and re-root moved data.

A memory stores each entry's start/end image relative to a *data root* recorded in its manifest as
an absolute path (`docs/architecture.md`, "Memory folder"). Loaded, every reference is absolute
again: under the recorded root, or under another root given by the user (`--data-root`) when the
data has moved. Memories written before roots were recorded keep their references as stored.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from robofailring.data.frame_ref import FrameRef
from robofailring.errors import MemoryFormatError


def is_file_reference(reference: str) -> bool:
    """False for in-memory frames (``<array>``) that have no file behind them."""
    return FrameRef.parse(reference).is_file


def absolute_reference(reference: str) -> str:
    """The reference as an absolute path string (in-memory references unchanged)."""
    return os.path.abspath(reference) if is_file_reference(reference) else reference


def common_root(references: Iterable[str]) -> Path | None:
    """The deepest folder holding every file reference, or None when there is none."""
    folders = {os.path.dirname(absolute_reference(ref)) for ref in references if is_file_reference(ref)}
    if not folders:
        return None
    return Path(os.path.commonpath(sorted(folders)))


def to_stored(reference: str, root: Path | None) -> str:
    """How a reference is written to disk: POSIX-relative to `root` when under it, else absolute."""
    if not is_file_reference(reference):
        return reference
    absolute = absolute_reference(reference)
    if root is not None:
        relative = os.path.relpath(absolute, root)
        if relative != os.pardir and not relative.startswith(os.pardir + os.sep):
            return PurePosixPath(Path(relative)).as_posix()
    return absolute


def resolve_stored(stored: str, root: Path | None) -> str:
    """The absolute reference of a stored one: relative ones are joined to `root`."""
    if not is_file_reference(stored) or root is None or os.path.isabs(stored):
        return stored
    return str(Path(root, *PurePosixPath(stored).parts))


def inside(reference: str, root: Path) -> bool:
    """Whether a reference's file lies in `root` once `..` is resolved (lexically: a dataset's own
    symbolic links are followed when read, not here)."""
    file = os.path.normpath(reference_file(reference))
    base = os.path.normpath(str(root))
    return file == base or file.startswith(base.rstrip(os.sep) + os.sep)


def resolve_inside(stored: str, root: Path) -> str:
    """`resolve_stored`, refused (MemoryFormatError naming it) when the reference lies outside `root`: a
    memory shared with you is untrusted, and an entry edited to `/home/you/private.png` or `../../x`
    must not make a recording or a VLM request carry that file."""
    resolved = resolve_stored(stored, root)
    if is_file_reference(resolved) and not inside(resolved, root):
        raise MemoryFormatError(
            f"reference {stored!r} lies outside the memory's data root {root}: refused (an edited or foreign "
            "memory? its images must lie under its data root, or under --data-root)"
        )
    return resolved


def storage_root(root: Path | None, references: Iterable[str]) -> Path | None:
    """The root a memory's references are stored under: `root` when it holds all of them, else the
    deepest folder that holds `root` and them (runs added from another dataset), so none is stored
    absolute."""
    files = [absolute_reference(ref) for ref in references if is_file_reference(ref)]
    if root is None:
        return common_root(files)
    if all(inside(ref, root) for ref in files):
        return root
    return Path(os.path.commonpath([str(root), *(os.path.dirname(reference_file(f)) for f in files)]))


def reroot(reference: str, old_root: Path, new_root: Path) -> str:
    """Move an absolute reference from under `old_root` to under `new_root` (others unchanged)."""
    stored = to_stored(reference, old_root)
    return resolve_stored(stored, new_root) if not os.path.isabs(stored) else reference


@dataclass(frozen=True)
class ReferenceCheck:
    """How many distinct file references resolve to an existing file."""

    total: int
    missing: tuple[str, ...] = field(default=())
    # those outside the folders named for the memory's images (`memory.image_roots`): never read
    outside: tuple[str, ...] = field(default=())

    @property
    def found(self) -> int:
        return self.total - len(self.missing)

    @property
    def ok(self) -> bool:
        return not self.missing and not self.outside

    def summary(self, *, hint: str = "") -> str:
        """One line: how many are missing or outside and the first path of each (empty when all are fine)."""
        parts = []
        if self.missing:
            parts.append(
                f"{len(self.missing)} of {self.total} reference image(s) of the memory not found "
                f"(first: {self.missing[0]}){hint}"
            )
        if self.outside:
            parts.append(
                f"{len(self.outside)} of {self.total} reference image(s) lie outside the folders named for them "
                f"(the data read, the memory's folder, --data-root), so they are not read nor recorded "
                f"(first: {self.outside[0]}); pass --data-root DIR, the folder they are in, if you trust it"
            )
        return "; ".join(parts)


def reference_file(reference: str) -> str:
    """The file behind a reference (`robofailring.data.frame_ref`): a video frame, an HDF5 row and a bag
    message live in their container's file (a ROS 2 bag is a folder)."""
    return FrameRef.parse(reference).file


def _is_there(file: str) -> bool:
    """A reference's file exists (an image, a video, a `.bag` file or a ROS 2 bag folder)."""
    return os.path.isfile(file) or os.path.isdir(file)


def check_references(references: Iterable[str]) -> ReferenceCheck:
    """Stat each distinct file reference once."""
    unique = sorted({ref for ref in references if is_file_reference(ref)})
    missing = tuple(ref for ref in unique if not _is_there(reference_file(ref)))
    return ReferenceCheck(total=len(unique), missing=missing)


def stored_resolver(
    recorded: str | None, source: str | None, data_root: Path | None
) -> tuple[Callable[[str], str] | None, Path | None]:
    """How to turn a saved memory's stored references into absolute ones, and the root used.

    Memories that record `data_root` store references relative to it; `data_root` given here
    replaces it (the data moved). Older memories stored references as given at build time: they
    resolve as they did (None: leave them), and a given `data_root` re-roots those that lay under
    the dataset root the manifest recorded as `source`. `recorded` is the manifest's `data_root`.
    """
    if recorded is not None:
        root = Path(data_root).resolve() if data_root is not None else Path(recorded)
        return (lambda ref: resolve_inside(ref, root)), root
    if data_root is None or source is None:
        return None, None
    new_root = Path(data_root).resolve()
    return (lambda ref: _reroot_old(ref, Path(source), new_root)), new_root


def _reroot_old(reference: str, source: Path, new_root: Path) -> str:
    """Re-root a format-1 reference: absolute under `source`, or relative to the build's cwd.

    A relative one such as ``data/aha/ep/front_0.png`` built from ``/home/u`` with the source
    ``/home/u/data/aha`` begins with the source's last folders; what follows them is kept.
    """
    if not is_file_reference(reference):
        return reference
    if os.path.isabs(reference):
        return reroot(reference, source, new_root)
    parts = PurePosixPath(Path(reference)).parts
    for shared in range(min(len(parts) - 1, len(source.parts)), 0, -1):
        if parts[:shared] == source.parts[-shared:]:
            return str(Path(new_root, *parts[shared:]))
    return reference


def relocate(reference: str, root: Path) -> str:
    """A reference that no longer exists, found again under `root` (where its dataset moved).

    The longest trailing part of its path that exists under `root` wins; a reference that exists,
    or is found nowhere under `root`, is returned unchanged.
    """
    if not is_file_reference(reference) or _is_there(reference_file(reference)):
        return reference
    ref = FrameRef.parse(reference)
    parts = Path(ref.file).parts
    for keep in range(len(parts) - 1, 0, -1):
        candidate = Path(root, *parts[-keep:])
        if _is_there(str(candidate)):
            return str(ref.moved(candidate))
    return reference
