"""JSON given by a user, parsed in one place: any fault is the project's error naming the file, never a traceback.

Python's parser recurses once per `[` or `{`, so a file of 100,000 brackets raises RecursionError, which
is neither a ValueError nor an OSError and would otherwise end the command in a traceback.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from robofailring.errors import DataError, RoboFailRingError


def parse_json(
    text: str | bytes,
    *,
    source: str,
    error: type[RoboFailRingError] = DataError,
    object_pairs_hook: Callable[[list[tuple[Any, Any]]], Any] | None = None,
) -> Any:
    """`text` as JSON; `error` naming `source` (a file, `file:line`) when it is not JSON, is not UTF-8,
    holds a number too long to read or nests lists or objects deeper than Python can recurse."""
    try:
        return json.loads(text, object_pairs_hook=object_pairs_hook)
    except RecursionError as fault:
        raise error(f"{source} nests lists or objects too deeply") from fault
    except ValueError as fault:  # JSONDecodeError, UnicodeDecodeError, a number past int's digit limit
        raise error(f"{source} is not valid JSON: {fault}") from fault
