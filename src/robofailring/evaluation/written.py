"""An evaluation's two files, `<name>.json` and `<name>.md`, written atomically: a held-out evaluation's
(`EvaluationResult`) or a cross-validation made alone (`FoldsAlone`), under the same names."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Protocol

from robofailring.atomic import write_text_atomic


class Tables(Protocol):
    """What an evaluation's files are written from: its name (the files' stem), its JSON and its Markdown."""

    @property
    def name(self) -> str: ...

    def to_dict(self) -> dict[str, Any]: ...

    def to_markdown(self) -> str: ...


def write_evaluation(result: Tables, out: Path) -> tuple[Path, Path]:
    """`<name>.json` and `<name>.md` under `out`, written atomically."""
    out = Path(out)
    json_path, md_path = out / f"{result.name}.json", out / f"{result.name}.md"
    write_text_atomic(json_path, json.dumps(result.to_dict(), indent=2), claim=True)
    write_text_atomic(md_path, result.to_markdown() + "\n", claim=True)
    return json_path, md_path
