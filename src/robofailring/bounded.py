"""Files another machine or person made, read within bounds: what they declare is checked before it is allocated.

A memory folder, an export or a dataset can be shared, so a file in it can be anything: a link to
`/dev/zero` (read until memory runs out), a FIFO (an `open` that never returns), or an `.npz` whose
member declares shape (1e11, 129) in a few bytes (NumPy allocates the declared array before reading
it). `open_regular` opens a file only when it is a regular file (a link to one is fine) of at most
`limit` bytes; `read_npz` reads an `.npz` of such a file only when each member's declared array fits in
the bytes the member holds. Each refusal is the caller's error naming the file.
"""

from __future__ import annotations

import contextlib
import math
import os
import stat
import zipfile
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import IO, Final

import numpy as np

from robofailring.errors import RoboFailRingError

GIB: Final[int] = 1 << 30
#: deflate expands one byte to at most 1,032: a member declaring more than that of its compressed size lies
DEFLATE_RATIO: Final[int] = 1032
Shape = tuple[int | None, ...]  # an array's expected shape: each side that size, or any where None


@contextlib.contextmanager
def open_regular(path: Path, *, limit: int, error: type[RoboFailRingError]) -> Iterator[IO[bytes]]:
    """`path` opened for reading in binary when it is a regular file of at most `limit` bytes; `error`
    naming it when it is a device, a FIFO, a socket or a folder (a link is followed to what it names), or
    larger. Opened without blocking, so a FIFO is refused rather than waited on."""
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as fault:
        raise error(f"cannot read {path}: {fault.strerror or fault}") from fault
    try:
        found = os.fstat(descriptor)
        if not stat.S_ISREG(found.st_mode):
            raise error(f"{path} is not a regular file (a device, a FIFO, a socket or a folder): refused")
        if found.st_size > limit:
            raise error(f"{path} has {found.st_size:,} bytes, more than the {limit:,} such a file may have")
        os.set_blocking(descriptor, True)
        handle = os.fdopen(descriptor, "rb")
    except BaseException:
        os.close(descriptor)
        raise
    with handle:
        yield handle


def read_regular(path: Path, *, limit: int, error: type[RoboFailRingError]) -> bytes:
    """The bytes of `path`, a regular file of at most `limit` bytes (`open_regular`)."""
    with open_regular(path, limit=limit, error=error) as handle:
        data = handle.read(limit + 1)
    if len(data) > limit:  # it grew since it was opened
        raise error(f"{path} has more than the {limit:,} bytes such a file may have")
    return data


def read_npz(
    path: Path,
    *,
    error: type[RoboFailRingError],
    names: Iterable[str] | None = None,
    limit: int = 64 * GIB,
    shapes: Mapping[str, Shape] | None = None,
) -> dict[str, np.ndarray]:
    """The arrays of the `.npz` file `path` (those in `names`, when given), without pickles, each read only
    when its declared shape and type fit the bytes its member holds and, for a member in `shapes` (what a
    manifest says), the declared shape is that one: both checked from the member's header, before anything is
    decompressed. `error` naming the file and the member otherwise, or when the file is not a regular file or
    not an `.npz`."""
    wanted = None if names is None else set(names)
    arrays: dict[str, np.ndarray] = {}
    with open_regular(path, limit=limit, error=error) as handle:
        try:
            with zipfile.ZipFile(handle) as archive:
                for member in archive.infolist():
                    name = member.filename.removesuffix(".npy")
                    if wanted is not None and name not in wanted:
                        continue
                    expected = None if shapes is None else shapes.get(name)
                    _check_member(archive, member, expected, where=f"{path}: {name}", error=error)
                    with archive.open(member) as stream:
                        arrays[name] = np.lib.format.read_array(stream, allow_pickle=False)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile) as fault:
            raise error(f"cannot read {path}: {fault}") from fault
    missing = sorted(wanted - set(arrays)) if wanted is not None else []
    if missing:
        raise error(f"{path} has no array {missing[0]!r}")
    return arrays


def _check_member(
    archive: zipfile.ZipFile,
    member: zipfile.ZipInfo,
    expected: Shape | None,
    *,
    where: str,
    error: type[RoboFailRingError],
) -> None:
    """`error` when `member` declares an array larger than the bytes it holds (or an object array), or of
    another shape than `expected`."""
    if member.compress_type != zipfile.ZIP_STORED and member.file_size > DEFLATE_RATIO * max(
        member.compress_size, 1
    ):
        raise error(
            f"{where} declares {member.file_size:,} bytes in {member.compress_size:,} compressed ones"
        )
    with archive.open(member) as stream:
        version = np.lib.format.read_magic(stream)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(stream)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(stream)
        header = stream.tell()
    if expected is not None and (
        len(shape) != len(expected)
        or any(want is not None and int(side) != want for side, want in zip(shape, expected, strict=True))
    ):
        shown = tuple("any" if want is None else want for want in expected)
        raise error(
            f"{where} declares shape {tuple(int(side) for side in shape)}, the manifest says {shown} "
            "(a damaged or crafted file)"
        )
    if dtype.hasobject:
        raise error(f"{where} holds Python objects (pickles), which are never read")
    declared = math.prod(int(side) for side in shape) * dtype.itemsize
    holds = member.file_size - header
    if declared > holds:
        raise error(
            f"{where} declares shape {tuple(shape)} of {dtype} ({declared:,} bytes), its member holds "
            f"{holds:,} (a damaged or crafted file)"
        )
