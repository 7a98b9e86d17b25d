"""Checks of a saved memory's entries, parsed once at load: a well-formed JSON file can still be wrong.

The manifest's checks live in `robofailring.memory.manifest`."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Final

from robofailring.data.grounding import parse_symbol
from robofailring.errors import MemoryFormatError, SymbolError

ENTRY_FIELDS: Final[tuple[str, ...]] = ("task", "symbol", "episode", "view", "start", "end")


def parse_entry(line: str, path: Path, number: int) -> dict[str, Any]:
    """One line of entries.jsonl as the entry's fields; its failure symbol must parse (paper Table 5)."""
    try:
        record = json.loads(line)
    except ValueError as error:  # not JSON, or a number too long to read
        raise MemoryFormatError(f"{path}:{number}: not JSON ({error})") from error
    if not isinstance(record, dict) or not set(ENTRY_FIELDS) <= set(record):
        raise MemoryFormatError(f"{path}:{number}: an entry is an object with {', '.join(ENTRY_FIELDS)}")
    wrong = [key for key in ENTRY_FIELDS if not isinstance(record[key], str)]
    if wrong:
        raise MemoryFormatError(f"{path}:{number}: {wrong[0]!r} must be a string, not {record[wrong[0]]!r}")
    try:
        parse_symbol(record["symbol"])
    except SymbolError as error:
        raise MemoryFormatError(f"{path}:{number}: {error}") from error
    return record
