"""Text from the data (task, episode and view names, reasons, paths) as it goes into the evaluation's
Markdown, escaped in one place: a `|` stays inside its table cell and `<b>` is shown, not rendered."""

from __future__ import annotations

import re
from typing import Final

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
