"""Crafted inputs shared by the fault, fuzz and property tests (issue 45, item 6): small files built to
break a parser's or reader's assumptions, each naming what it declares."""

from __future__ import annotations

import struct
from pathlib import Path

DEEP: int = 100_000  # brackets: far past Python's recursion limit (1,000), a 200 KB file


def nested_json(depth: int = DEEP, *, opener: str = "[") -> str:
    """JSON text nesting `depth` lists (`[`) or objects (`{`), valid at any depth but too deep to parse."""
    if opener == "{":
        return '{"a":' * depth + "0" + "}" * depth
    return "[" * depth + "]" * depth


# A flat Faiss index file (`IndexFlatIP`, as `faiss.write_index` writes it): "IxFI", d (int32), ntotal
# (int64), two unused int64, is_trained (1 byte), metric (int32), then its vectors' length in floats
# (uint64) and the floats.
NTOTAL_AT, FLOATS_AT = 8, 37
GIB_OF_FLOATS = 2**30 // 4


def declare_in_index(path: Path, *, entries: int | None = None, floats: int | None = None) -> Path:
    """Rewrite a flat Faiss index's header to declare `entries` vectors and/or `floats` floats of them,
    the file's length unchanged (`50 * GIB_OF_FLOATS`: 50 GiB in a file of a few KB)."""
    data = bytearray(path.read_bytes())
    assert data[:4] == b"IxFI", data[:4]
    if entries is not None:
        data[NTOTAL_AT : NTOTAL_AT + 8] = struct.pack("<q", entries)
    if floats is not None:
        data[FLOATS_AT : FLOATS_AT + 8] = struct.pack("<Q", floats)
    path.write_bytes(bytes(data))
    return path
