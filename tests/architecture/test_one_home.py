"""One home per concept: a frame reference's forms are written and parsed only in `robofailring.data.frame_ref`
(no second parser, no second reader of `#frame=` or a bag message), and a scoring rule's command-line option
comes from the rule registry, not a list of rule names (docs/architecture.md)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FRAME_REF = ROOT / "src" / "robofailring" / "data" / "frame_ref.py"
MARKERS = ("#frame=", "&message=", "#topic=")


def _modules() -> list[Path]:
    return [*(ROOT / "src" / "robofailring").rglob("*.py"), *(ROOT / "rfr_viz").rglob("*.py")]


def _literals(path: Path) -> list[str]:
    """The module's string constants (f-strings' parts included), less its docstrings."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    documented = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, documented) and node.body and isinstance(node.body[0], ast.Expr)
    }
    return [
        node.value
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
    ]


def test_frame_reference_markers_live_in_their_module_only() -> None:
    found = {
        (str(path.relative_to(ROOT)), marker)
        for path in _modules()
        if path != FRAME_REF
        for text in _literals(path)
        for marker in MARKERS
        if marker in text
    }
    # a signal's reference (`<bag>#topic=<topic>&field=<f>`) names a topic's field, not a frame
    assert found <= {("src/robofailring/data/layouts/rosbag_signals.py", "#topic=")}, found
    assert {marker for text in _literals(FRAME_REF) for marker in MARKERS if marker in text} == set(MARKERS)


def test_no_second_frame_reference_reader() -> None:
    defined = {
        (str(path.relative_to(ROOT)), node.name)
        for path in _modules()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.FunctionDef)
        and node.name.startswith("read_")
        and node.name.endswith(("_reference", "_ref"))
    }
    assert defined == set(), defined
