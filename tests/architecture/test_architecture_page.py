"""docs/architecture.md names every module where it lives: each `<package>/<module>.py` of `robofailring` and
`rfr_viz` in its package's rows of the page's two tables (a top-level module in the `(top)` row), and every
dataset layout of `LAYOUTS` in the detection order the page gives."""

from __future__ import annotations

import re
from pathlib import Path

from robofailring.data.layouts import LAYOUTS

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "architecture.md"
# each package root and the heading of the page's table for it
TABLES = {ROOT / "src" / "robofailring": "## The library", ROOT / "rfr_viz": "## Rerun"}
TOP = "(top)"


def _named(heading: str) -> dict[str, set[str]]:
    """The modules a table names, by its package column (a row with an empty package cell: the one above)."""
    table = PAGE.read_text().partition(f"\n{heading}")[2].partition("\n## ")[0]
    named: dict[str, set[str]] = {}
    package = None
    for line in table.splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if not line.startswith("|") or len(cells) < 3 or cells[0] == "package" or cells[0].startswith("---"):
            continue
        package = cells[0].strip("`").rstrip("/") or package
        named.setdefault(package or TOP, set()).update(re.findall(r"`(?:\w+/)*(\w+\.py)`", cells[1]))
    return named


def test_every_module_is_named_in_its_packages_rows() -> None:
    missing = []
    for root, heading in TABLES.items():
        named = _named(heading)
        assert len(named) > 5, heading  # the table was found
        for module in sorted(root.rglob("*.py")):
            where = module.relative_to(root)
            if module.name == "__init__.py" or "__pycache__" in where.parts:
                continue
            package = where.parts[0] if len(where.parts) > 1 else TOP
            if module.name not in named.get(package, set()):
                missing.append(f"{root.name}/{where}")
    assert missing == []


def test_the_layouts_are_listed_in_their_detection_order() -> None:
    (order,) = re.findall(r"`LAYOUTS` in detection order \(([^:]+):", PAGE.read_text())
    assert [name.strip() for name in order.split(",")] == [layout.name for layout in LAYOUTS]
