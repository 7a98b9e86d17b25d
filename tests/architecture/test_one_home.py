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


ENCODERS = ROOT / "src" / "robofailring" / "encoders"
#: Each encoder kind's name and the one module besides the registry (`encoders/spec.py`) that may name it.
KIND_HOMES = {
    "pixels": ENCODERS / "pixels.py",
    "open_clip": ENCODERS / "openclip.py",
    "timm": ENCODERS / "timm_backbone.py",
    "trained": ENCODERS / "trained.py",
}
#: An ONNX export's recorded preprocessing is `open_clip` (open_clip's own transform) or `square`: a form of
#: `export.json`, not the encoder kind.
PREPROCESSING = ENCODERS / "preprocess.py"


def _kind_branches(path: Path) -> set[str]:
    """The encoder kind names `path` branches on: compared (`==`, `!=`, `in`, `not in`, alone or in a tuple,
    list or set) or asked of a string (`startswith("trained:")`)."""

    def named(node: ast.AST) -> set[str]:
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            return {node.value} & set(KIND_HOMES)
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            return {name for element in node.elts for name in named(element)}
        return set()

    found: set[str] = set()
    comparisons = (ast.Eq, ast.NotEq, ast.In, ast.NotIn)
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Compare) and any(isinstance(op, comparisons) for op in node.ops):
            found |= {name for operand in [node.left, *node.comparators] for name in named(operand)}
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr in ("startswith", "endswith", "removeprefix")
            and node.args
            and isinstance(node.args[0], ast.Constant)
        ):
            found |= {name for name in KIND_HOMES if str(node.args[0].value).startswith(name)}
    return found


def test_only_the_registry_and_its_own_module_name_an_encoder_kind() -> None:
    """An encoder kind is registered once (`encoders/spec.py`, docs/architecture.md "Adding an encoder kind"):
    no other module branches on a kind's name, so a new kind changes no other file."""
    found = {
        (str(path.relative_to(ROOT)), name)
        for path in _modules()
        if path != ENCODERS / "spec.py"
        for name in _kind_branches(path)
        if path != KIND_HOMES[name] and not (path == PREPROCESSING and name == "open_clip")
    }
    assert found == set(), found
