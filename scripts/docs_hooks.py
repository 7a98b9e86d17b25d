"""MkDocs hooks (mkdocs.yml `hooks:`): the command-line page completed from the command itself.

docs/cli.md holds the verbs' overview in words and one marker line; at build time the marker becomes
every verb's arguments and options as `robofailring VERB --help` states them
(`rfr_viz.cli.reference`), so the site's reference is the checkout's own command.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

CHECKOUT = Path(__file__).resolve().parents[1]


def on_page_markdown(markdown: str, *, page: Any, config: Any, files: Any) -> str:
    """Replace docs/cli.md's marker with the generated reference; other pages pass unchanged."""
    for folder in (CHECKOUT, CHECKOUT / "src"):  # this checkout's packages, before any installed copy
        if str(folder) not in sys.path:
            sys.path.insert(0, str(folder))
    from rfr_viz.cli.reference import MARKER, cli_reference

    if MARKER not in markdown:
        return markdown
    return markdown.replace(MARKER, cli_reference(level=3))
