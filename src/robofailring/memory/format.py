"""Reading a saved memory's JSONL files (`entries.jsonl`, `success_runs.jsonl`), checked once at load.

A well-formed JSON file can still be wrong: each row is parsed into its object here, and a bad row
is a MemoryFormatError naming the file and line. The manifest's checks live in
`robofailring.memory.manifest`."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final, TypeGuard, TypeVar

from robofailring.bounded import GIB, open_regular, read_regular
from robofailring.data.grounding import Vocabulary, parse_symbol
from robofailring.data.vocabulary import read_vocabulary
from robofailring.errors import MemoryFormatError, SymbolError, VocabularyError
from robofailring.jsontext import parse_json

ENTRY_FIELDS: Final[tuple[str, ...]] = ("task", "symbol", "episode", "view", "start", "end")
JSONL_LIMIT: Final[int] = 16 * GIB  # entries.jsonl, success_runs.jsonl: tens of millions of rows
LINE_LIMIT: Final[int] = 1 << 24  # one row (an entry, a success run's frame list): 16 MiB
MANIFEST_LIMIT: Final[int] = 1 << 28  # manifest.json: 256 MiB

Row = TypeVar("Row")


def is_number(value: Any) -> TypeGuard[float]:
    """A JSON number (an int or a float, not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_finite_number(value: Any) -> bool:
    """A JSON number that is finite."""
    return is_number(value) and math.isfinite(value)


def is_whole(value: Any) -> TypeGuard[int]:
    """A JSON whole number (an int, not a bool)."""
    return isinstance(value, int) and not isinstance(value, bool)


def read_json(path: Path) -> Any:
    """A memory's JSON file (`manifest.json`), a regular file of at most `MANIFEST_LIMIT` bytes, parsed."""
    text = read_regular(path, limit=MANIFEST_LIMIT, error=MemoryFormatError)
    return parse_json(text, source=str(path), error=MemoryFormatError)


def read_jsonl(path: Path, parse: Callable[[Any], Row], *, what: str) -> list[Row]:
    """Every non-blank line of `path` as JSON, turned into a row by `parse`.

    `path` is read only when it is a regular file of at most `JSONL_LIMIT` bytes, and a line only up to
    `LINE_LIMIT` bytes (`robofailring.bounded`: a link to `/dev/zero` was read until memory ran out).
    `parse` raises MemoryFormatError, TypeError, KeyError or ValueError for a row it cannot use;
    the error names `path:<line>` and `what` a row is (e.g. "entry").
    """
    rows: list[Row] = []
    try:
        with open_regular(path, limit=JSONL_LIMIT, error=MemoryFormatError) as handle:
            for number, line in enumerate(iter(lambda: handle.readline(LINE_LIMIT + 1), b""), 1):
                if len(line) > LINE_LIMIT:
                    raise MemoryFormatError(f"{path}:{number} is longer than {LINE_LIMIT:,} bytes")
                if not line.strip():
                    continue
                record = parse_json(line.decode("utf-8"), source=f"{path}:{number}", error=MemoryFormatError)
                try:
                    rows.append(parse(record))
                except MemoryFormatError as error:
                    raise MemoryFormatError(f"{path}:{number}: {error}") from error
                except (TypeError, KeyError, ValueError) as error:
                    raise MemoryFormatError(f"{path}:{number}: bad {what} ({error})") from error
    except UnicodeDecodeError as error:
        raise MemoryFormatError(f"{path} is not UTF-8 text: {error}") from error
    except OSError as error:
        raise MemoryFormatError(f"cannot read {path}: {error}") from error
    return rows


def parse_entry(record: Any, vocabulary: Vocabulary | None = None) -> dict[str, Any]:
    """One row of entries.jsonl as the entry's fields; its failure symbol must parse (paper Table 5
    and the memory's `vocabulary`); an optional `description` is the label's own text, optional
    `frame` and `length` (together) the moment of the run a dense entry is."""
    if not isinstance(record, dict) or not set(ENTRY_FIELDS) <= set(record):
        raise MemoryFormatError(f"an entry is an object with {', '.join(ENTRY_FIELDS)}")
    wrong = [key for key in ENTRY_FIELDS if not isinstance(record[key], str)]
    if wrong:
        raise MemoryFormatError(f"{wrong[0]!r} must be a string, not {record[wrong[0]]!r}")
    written = record.get("description")
    if written is not None and not isinstance(written, str):
        raise MemoryFormatError(f"'description' must be a string, not {written!r}")
    try:
        parse_symbol(record["symbol"], vocabulary)
    except SymbolError as error:
        raise MemoryFormatError(str(error)) from error
    return {key: record[key] for key in ENTRY_FIELDS} | {
        "written": written,
        "vocabulary": vocabulary,
        **_moment(record),
    }


def _moment(record: dict[str, Any]) -> dict[str, int | None]:
    """`frame` and `length` of an entry row: both absent (the run's end), or whole numbers 0 ≤ frame < length."""
    frame, length = record.get("frame"), record.get("length")
    if frame is None and length is None:
        return {"frame": None, "length": None}
    whole = [key for key, value in (("frame", frame), ("length", length)) if type(value) is not int]
    if whole:
        raise MemoryFormatError(
            f"{whole[0]!r} must be a whole number (with 'frame' and 'length' together), not {record.get(whole[0])!r}"
        )
    assert isinstance(frame, int) and isinstance(length, int)
    if not 0 <= frame < length:
        raise MemoryFormatError(f"'frame' must lie in 0 … length − 1 = {length - 1}, not {frame}")
    return {"frame": frame, "length": length}


def stored_vocabulary(directory: Path, name: str | None) -> Vocabulary | None:
    """The vocabulary file a memory's manifest names (`name`, in the memory's own folder), or None."""
    if name is None:
        return None
    if Path(name).name != name:
        raise MemoryFormatError(
            f"{directory / 'manifest.json'}: 'vocabulary' must name a file in the memory's folder"
        )
    try:
        return read_vocabulary(directory / name)
    except VocabularyError as error:
        raise MemoryFormatError(f"{directory}: its vocabulary cannot be read: {error}") from error
