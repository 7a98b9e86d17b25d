"""The folders a memory's or a report's images may be read from: those the user named, never a file's say.

A memory or a report shared with you is untrusted: the data root its manifest records, the `roots` a
report lists and every reference in them may have been edited (`"/"` and `home/you/Pictures/p.jpg`). So
the folders an image may come from are the ones named where it was opened (`--data-root`, the memory's
own folder, the data a verb reads, a report file's folder; docs/memory.md, "Moving or sharing a memory"),
and a reference is judged by the file it names once every symbolic link is followed: a link inside the
data that points out of it is outside too.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from robofailring.memory.references import absolute_reference, is_file_reference, reference_file


def real_path(path: str | Path) -> Path:
    """`path` absolute, with `..` and every symbolic link resolved (as far as it exists)."""
    return Path(os.path.realpath(os.path.abspath(path)))


@dataclass(frozen=True)
class ImageRoots:
    """Folders the user named (resolved): a file reference is read only when its real file lies in one."""

    folders: tuple[Path, ...] = ()

    @classmethod
    def of(cls, *folders: str | Path | None) -> ImageRoots:
        """The folders given (None ones left out), resolved, each once."""
        return cls(tuple(dict.fromkeys(real_path(folder) for folder in folders if folder is not None)))

    def joined(self, *others: ImageRoots) -> ImageRoots:
        """These folders and those of `others`."""
        return ImageRoots.of(*self.folders, *(folder for other in others for folder in other.folders))

    def holds(self, reference: str) -> bool:
        """Whether the reference may be read: an in-memory frame, or a file that is (after its links) inside
        one of the folders (a path compared by its parts, never as a string prefix)."""
        if not is_file_reference(reference):
            return True
        file = real_path(reference_file(absolute_reference(reference)))
        return any(file.is_relative_to(folder) for folder in self.folders)

    def outside(self, references: Iterable[str]) -> list[str]:
        """The distinct references, in order, that may not be read."""
        return [reference for reference in dict.fromkeys(references) if not self.holds(reference)]

    def __str__(self) -> str:
        return ", ".join(map(str, self.folders)) or "none named"

    def refusal(self, reference: str) -> str:
        """Why `reference` is not read, naming it and the folders (one line)."""
        return (
            f"image {reference} lies outside the folders named for it ({self}): not read; pass --data-root DIR, "
            "the folder its images are in, if you trust it"
        )
