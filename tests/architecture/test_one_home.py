"""One home per concept: a frame reference's forms are written and parsed only in `robofailring.data.frame_ref`
(no second parser, no second reader of `#frame=` or a bag message), a scoring rule's command-line option
comes from the rule registry, not a list of rule names, and the modalities' names (`both`, `cameras`,
`signals`: a modality, the signals' view, a fusion group) live in `robofailring.memory.signals.modality`, which
alone splits views by modality, an encoder kind is named only by the registry and its own module, and each
setting's default is one named constant (docs/architecture.md)."""

from __future__ import annotations

import ast
from pathlib import Path

from robofailring.encoders.spec import kinds

ROOT = Path(__file__).resolve().parents[2]
FRAME_REF = ROOT / "src" / "robofailring" / "data" / "frame_ref.py"
MARKERS = ("#frame=", "&message=", "#topic=")
MODALITY = ROOT / "src" / "robofailring" / "memory" / "signals" / "modality.py"
MODALITY_NAMES = frozenset({"both", "cameras", "signals"})


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


def _names_a_modality(node: ast.AST | None, *, only: bool = False) -> bool:
    """`node` is one of the modalities' names as a string, or a tuple, list or set holding one (`only`: holding
    nothing else, as a tuple of names assigned does; a manifest's key order holds `signals` among its keys)."""
    if isinstance(node, ast.Constant):
        return node.value in MODALITY_NAMES
    if not isinstance(node, (ast.Tuple, ast.List, ast.Set)) or not node.elts:
        return False
    named = [_names_a_modality(element, only=only) for element in node.elts]
    return all(named) if only else any(named)


def _modality_literals(path: Path) -> list[tuple[int, str]]:
    """Where `path` uses a modality's, view's or fusion group's name as a value of its own: compared (`==`, `!=`,
    `in` a tuple of names), iterated over (`for name in ("cameras", "signals")`), given a name (`BOTH = "both"`), or a default or
    keyword argument (`modality: str = "both"`). A JSON key (`{"signals": …}`, `record.get("signals")`) is not
    one: it names a section of a file, written and read by the section's module."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        used: list[ast.AST | None] = []
        only = False
        if isinstance(node, ast.Compare):  # `"signals" in section`, a JSON key looked up, is not one
            keyed = isinstance(node.ops[0], (ast.In, ast.NotIn)) and isinstance(node.left, ast.Constant)
            used = [*([] if keyed else [node.left]), *node.comparators]
        elif isinstance(node, (ast.For, ast.AsyncFor, ast.comprehension)):
            used = [node.iter]
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            used, only = [node.value], True
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            used = [*node.args.defaults, *node.args.kw_defaults]
        elif isinstance(node, ast.keyword):
            used = [node.value]
        found += [
            (value.lineno, ast.unparse(value))
            for value in used
            if value is not None and _names_a_modality(value, only=only)
        ]
    return found


def test_modality_names_live_in_their_module_only() -> None:
    found = {
        f"{path.relative_to(ROOT)}:{line}: {text}"
        for path in _modules()
        if path != MODALITY
        for line, text in _modality_literals(path)
    }
    assert found == set()
    assert len(_modality_literals(MODALITY)) >= 6  # the home was found, and names them


def test_views_are_split_by_modality_in_one_function() -> None:
    """No module but the home keeps or drops views by comparing each with the signals' view (a filter in a
    comprehension or a lambda): `split_views` and `judged_views` do that, for every caller."""

    def filters(tree: ast.AST) -> list[ast.AST]:
        conditions: list[ast.AST] = []
        for node in ast.walk(tree):
            if isinstance(node, ast.comprehension):
                conditions += node.ifs
            elif isinstance(node, ast.Lambda):
                conditions.append(node.body)
        return conditions

    splitting = {
        str(path.relative_to(ROOT))
        for path in _modules()
        if path != MODALITY
        for condition in filters(ast.parse(path.read_text(encoding="utf-8")))
        for node in ast.walk(condition)
        if isinstance(node, ast.Name) and node.id == "SIGNALS_VIEW"
    }
    assert splitting == set()
    assert "SIGNALS_VIEW" in {
        node.id
        for condition in filters(ast.parse(MODALITY.read_text()))
        for node in ast.walk(condition)
        if isinstance(node, ast.Name)
    }


ENCODERS = ROOT / "src" / "robofailring" / "encoders"
#: Each registered encoder kind's name and the one module besides the registry (`encoders/spec.py`) that may
#: name it, read from the registry: a kind registered later is covered without a line here.
KIND_HOMES = {
    kind.name: (ROOT / "src" / Path(*kind.module.split("."))).with_suffix(".py") for kind in kinds()
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


#: The settings a user gives (a value's options, a job's, a detector's): each default is one named constant
#: where the setting is defined (`DEFAULT_K`, `DEFAULT_STRIDE`, `DEFAULT_TARGET_FPR`, `DEFAULT_BAND`, …), never a
#: literal repeated in a signature or a field.
SETTINGS = frozenset(
    {
        "stride", "k", "modality", "target_fpr", "band", "fusion", "band_scope", "pairing", "failure_frames",
        "encoder", "runtime", "device", "success_step", "signals", "signal_features", "signal_start_weight",
    }
)  # fmt: skip
#: A name that is no setting where it is used: a map's own neighbour count, a blueprint's "has signals" flag.
OTHER_MEANINGS = {("rfr_viz/panels/umap_layout.py", "knn_purity", "k")}


def _literal_defaults(path: Path) -> set[tuple[str, str, str]]:
    """(module, function or class, name) of each setting given a literal default (a number or a string) there."""
    found = set()
    where = str(path.relative_to(ROOT))
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        pairs: list[tuple[str, ast.expr | None]] = []
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            arguments = node.args
            positional = [*arguments.posonlyargs, *arguments.args]
            defaults = [None] * (len(positional) - len(arguments.defaults)) + list(arguments.defaults)
            pairs += [(a.arg, d) for a, d in zip(positional, defaults, strict=True)]
            pairs += [(a.arg, d) for a, d in zip(arguments.kwonlyargs, arguments.kw_defaults, strict=True)]
        elif isinstance(node, ast.ClassDef):
            pairs += [
                (statement.target.id, statement.value)
                for statement in node.body
                if isinstance(statement, ast.AnnAssign) and isinstance(statement.target, ast.Name)
            ]
        else:
            continue
        for name, default in pairs:
            literal = isinstance(default, ast.Constant) and isinstance(default.value, (int, float, str))
            if name in SETTINGS and literal and not isinstance(default.value, bool):  # type: ignore[union-attr]
                found.add((where, node.name, name))
    return found - OTHER_MEANINGS


def test_every_settings_default_is_its_one_constant() -> None:
    found = set().union(*(_literal_defaults(path) for path in _modules()))
    assert found == set(), sorted(found)
