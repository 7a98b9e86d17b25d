"""Checks of a saved memory's content, parsed once at load: a well-formed JSON file can still be wrong."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Final

from robofailring.errors import MemoryFormatError, SymbolError
from robofailring.grounding import parse_symbol

ENTRY_FIELDS: Final[tuple[str, ...]] = ("task", "symbol", "episode", "view", "start", "end")


def check_manifest(manifest: Any, path: Path) -> dict[str, Any]:
    """The manifest as a dict, or MemoryFormatError naming the field that is wrong."""
    if not isinstance(manifest, dict):
        raise MemoryFormatError(
            f"{path} holds a JSON {type(manifest).__name__}, not a memory manifest object"
        )
    for key in ("encoder", "dim", "count"):
        if key not in manifest:
            raise MemoryFormatError(f"{path} lacks {key!r}")
    if not isinstance(manifest["encoder"], str):
        raise MemoryFormatError(f"{path}: 'encoder' must be a string, not {manifest['encoder']!r}")
    for key in ("dim", "count"):
        value = manifest[key]
        if not isinstance(value, int) or isinstance(value, bool) or value < 0:
            raise MemoryFormatError(f"{path}: {key!r} must be a whole number ≥ 0, not {value!r}")
    calibration = manifest.get("calibration")
    if calibration is not None:
        if not isinstance(calibration, dict):
            raise MemoryFormatError(
                f"{path}: 'calibration' must be an object with 'delta' and 'encoder', not {calibration!r}; "
                "remove it and run `robofailring calibrate` again"
            )
        delta = calibration.get("delta")
        if not isinstance(delta, (int, float)) or isinstance(delta, bool) or not math.isfinite(delta):
            raise MemoryFormatError(f"{path}: calibration 'delta' must be a finite number, not {delta!r}")
    return manifest


def parse_entry(line: str, path: Path, number: int) -> dict[str, Any]:
    """One line of entries.jsonl as the entry's fields; its failure symbol must parse (paper Table 5)."""
    try:
        record = json.loads(line)
    except json.JSONDecodeError as error:
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
