"""Text from the data (task, episode and view names, reasons, paths) as it goes into the evaluation's
Markdown, escaped in one place: a `|` stays inside its table cell and `<b>` is shown, not rendered; and the
list of what the loaders did not read, which every evaluation's tables end with."""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Final

from robofailring.data.model import Skipped

# what Markdown would read as markup: backslash, code, emphasis, links, HTML, entities, cells, strikes;
# `_` only at a word's edge (`pick_cube` reads as it is: an underscore inside a word emphasises nothing)
_MARKUP: Final = re.compile(r"[\\`*\[\]<>&|~]|(?<![0-9A-Za-z])_|_(?![0-9A-Za-z])")


def markdown_text(text: object, *, code: bool = False) -> str:
    """`text` on one line, read by Markdown as the characters it is (each markup character escaped with a
    backslash); `code`: as a code span, unless it holds a backtick, a `|` or a backslash."""
    flat = " ".join(str(text).split())
    if code and flat and not {"`", "|", "\\"} & set(flat):  # a code span takes them literally, or not at all
        return f"`{flat}`"
    return _MARKUP.sub(lambda match: "\\" + match[0], flat)


def skipped_inputs_markdown(skipped: Sequence[Skipped], *, shown: int = 20) -> list[str]:
    """What the loaders did not read, for the tables: the first `shown` with their reason (all in the JSON)."""
    if not skipped:
        return []
    lines = ["", f"Not read from the data ({len(skipped)}):", ""]
    lines += [
        f"- {markdown_text(item.path, code=True)}: {markdown_text(item.reason)}" for item in skipped[:shown]
    ]
    if len(skipped) > shown:
        lines.append(f"- … and {len(skipped) - shown} more (all in the JSON file)")
    return lines
