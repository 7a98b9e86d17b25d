"""A memory's Faiss index files read without trusting the sizes they declare.

`faiss.read_index` allocates what a file's header declares before reading it: a 100 KB `index.faiss`
whose header claims 50 GiB of vectors is a `std::bad_alloc` or the out-of-memory killer (Faiss itself
refuses only a vector past 1 TiB). So the header is read first and checked against what the manifest
says the file holds (entries and their dimension) and against the file's length: every kind the
project writes stores at least one byte per dimension per entry, and a flat index exactly its declared
vectors (`IxFI`, `IxF2`: the header, then the count of floats, then the floats). The inverted files'
inner sizes (list lengths, codebooks) are not parsed: Faiss reads those as they are.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Final

import faiss

from robofailring.bounded import GIB, open_regular
from robofailring.errors import MemoryFormatError

# fourcc, d (int32), ntotal (int64), two unused int64, is_trained (bool), metric_type (int32): Faiss's
# `read_index_header`, which every index kind reads first
_HEADER: Final[struct.Struct] = struct.Struct("<4siqqq?i")
_FLAT: Final[frozenset[bytes]] = frozenset({b"IxFI", b"IxF2", b"IxFl"})
_FLOATS: Final[struct.Struct] = struct.Struct("<Q")  # a flat index's vector data: its length in floats
INDEX_LIMIT: Final[int] = 256 * GIB  # a regular file (never a link to a device) of at most this


def read_index_file(path: Path, *, count: int, dim: int | None = None) -> faiss.Index:
    """The index at `path`, read only when its header declares `count` entries (of `dim` dimensions, when
    given) and no more bytes than the file holds; MemoryFormatError naming the file otherwise."""
    check_index_file(path, count=count, dim=dim)
    try:
        return faiss.read_index(str(path))
    except RuntimeError as error:
        raise MemoryFormatError(f"cannot read Faiss index {path}: {error}") from error


def check_index_file(path: Path, *, count: int, dim: int | None = None) -> None:
    """MemoryFormatError naming `path` when its header declares other than `count` entries (of `dim`), or
    more vector bytes than the file holds (see the module's docstring); a file too short for a header is
    left to Faiss, which refuses it without allocating."""
    try:
        with open_regular(path, limit=INDEX_LIMIT, error=MemoryFormatError) as handle:
            head = handle.read(_HEADER.size + 4 + _FLOATS.size)
            size = handle.seek(0, 2)
    except OSError as error:
        raise MemoryFormatError(f"cannot read Faiss index {path}: {error.strerror or error}") from error
    if len(head) < _HEADER.size:
        return
    fourcc, d, ntotal, _, _, _, metric = _HEADER.unpack_from(head)
    if ntotal != count or (dim is not None and d != dim):
        expected = f"{count} entries" + (f" of dimension {dim}" if dim is not None else "")
        raise MemoryFormatError(f"{path} declares {ntotal} entries of dimension {d}, the memory {expected}")
    if d < 1 or ntotal * d > size:
        raise MemoryFormatError(
            f"{path} declares {ntotal} entries of dimension {d}, more than its {size:,} bytes hold "
            "(a damaged or crafted index)"
        )
    if fourcc not in _FLAT:
        return
    start = _HEADER.size + (4 if metric > 1 else 0)  # a metric argument (a float) for metrics past L2
    if len(head) < start + _FLOATS.size:
        return
    (floats,) = _FLOATS.unpack_from(head, start)
    if floats != ntotal * d or start + _FLOATS.size + 4 * floats > size:
        raise MemoryFormatError(
            f"{path} declares {4 * floats:,} bytes of vectors for {ntotal} entries of dimension {d}, "
            f"its {size:,} bytes hold {max(0, size - start - _FLOATS.size):,} (a damaged or crafted index)"
        )
