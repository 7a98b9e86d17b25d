"""Crafted inputs shared by the fault, fuzz and property tests (issue 45, item 6): small files built to
break a parser's or reader's assumptions, each naming what it declares."""

from __future__ import annotations

DEEP: int = 100_000  # brackets: far past Python's recursion limit (1,000), a 200 KB file


def nested_json(depth: int = DEEP, *, opener: str = "[") -> str:
    """JSON text nesting `depth` lists (`[`) or objects (`{`), valid at any depth but too deep to parse."""
    if opener == "{":
        return '{"a":' * depth + "0" + "}" * depth
    return "[" * depth + "]" * depth
