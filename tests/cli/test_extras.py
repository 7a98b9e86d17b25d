"""The extras (docs/install.md, "Install"): pyproject.toml and `robofailring.extras.EXTRAS` agree, every import of
an extra's module is guarded by `needs_extra`, and without the extras the command starts and a verb
that needs one ends in one line naming it."""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from robofailring.cli.exit_codes import exit_code_for
from robofailring.errors import MissingExtraError, RoboFailRingError
from robofailring.extras import EXTRAS, needs_extra, require

ROOT = Path(__file__).resolve().parents[2]
SOURCES = sorted([*(ROOT / "src" / "robofailring").rglob("*.py"), *(ROOT / "rfr_viz").rglob("*.py")])
EXTRA_MODULES = {module for modules in EXTRAS.values() for module in modules}


def _requirement_names(requirements: list[str]) -> set[str]:
    return {re.split(r"[\[<>=!~; ]", r, maxsplit=1)[0].lower().replace("_", "-") for r in requirements}


def test_pyproject_extras_install_what_the_table_says() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    core = _requirement_names(project["dependencies"])
    for extra, modules in EXTRAS.items():
        assert set(modules.values()) <= _requirement_names(extras[extra]), extra
        assert not set(modules.values()) & core, f"{extra}'s packages are in the core install"
    assert extras["all"] == [f"robofailring[{','.join(EXTRAS)}]"]
    # dev and docs are tools (the tests, the docs site), never imported by the packages
    assert set(extras) == {*EXTRAS, "all", "dev", "docs"}


def test_the_install_docs_list_every_extra() -> None:
    """README.md and docs/install.md name each extra, so none (onnx, ray) is found only in pyproject.toml."""
    table = (ROOT / "docs" / "install.md").read_text()
    readme = (ROOT / "README.md").read_text()
    assert [extra for extra in EXTRAS if f"| `{extra}` |" not in table] == []
    assert [extra for extra in EXTRAS if f"`{extra}`" not in readme] == []


def _guarded_by(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> tuple[str | None, bool]:
    """(the extra of the enclosing `with needs_extra(...)`, whether under `if TYPE_CHECKING:`)."""
    while node in parents:
        node = parents[node]
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING":
            return None, True
        if isinstance(node, ast.With):
            for item in node.items:
                call = item.context_expr
                if isinstance(call, ast.Call) and ast.unparse(call.func) == "needs_extra":
                    return ast.literal_eval(call.args[0]), False
    return None, False


def test_every_import_of_an_extras_module_is_guarded() -> None:
    unguarded = []
    for path in SOURCES:
        tree = ast.parse(path.read_text())
        parents = {child: parent for parent in ast.walk(tree) for child in ast.iter_child_nodes(parent)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in EXTRA_MODULES:
                    continue
                extra, typing_only = _guarded_by(node, parents)
                if not typing_only and (extra is None or top not in EXTRAS[extra]):
                    unguarded.append(f"{path.relative_to(ROOT)}:{node.lineno} {name} (in {extra})")
    assert len(SOURCES) > 100  # the tree was found
    assert unguarded == []


def test_a_missing_module_of_the_extra_is_an_error_naming_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "umap", None)  # as if umap-learn were not installed
    with pytest.raises(MissingExtraError) as caught, needs_extra("viz"):
        import umap  # noqa: F401
    error = caught.value
    assert (error.extra, error.name) == ("viz", "umap")
    assert "umap-learn is not installed" in str(error) and "install robofailring[viz]" in str(error)
    assert isinstance(error, ImportError) and isinstance(error, RoboFailRingError)
    assert exit_code_for(error) == 1  # an error of the environment (robofailring.cli.exit_codes)


def test_needs_extra_leaves_other_missing_modules_as_they_are() -> None:
    with pytest.raises(ModuleNotFoundError) as other, needs_extra("viz"):
        import no_such_module  # noqa: F401
    assert not isinstance(other.value, MissingExtraError)
    with pytest.raises(ModuleNotFoundError) as part, needs_extra("video"):
        import av.no_such_part  # noqa: F401  (av is installed here: a part of it missing is no missing extra)
    assert not isinstance(part.value, MissingExtraError)
    with pytest.raises(KeyError, match="unknown extra 'vis'"), needs_extra("vis"):
        pass


def test_require_checks_before_any_work() -> None:
    require("vlm")  # installed here
    blocked = "import sys; sys.modules['httpx'] = None\n"
    probe = blocked + (
        "from robofailring.extras import require\n"
        "try:\n    require('vlm')\nexcept ImportError as error:\n    print(error)\n"
    )
    printed = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert "httpx is not installed" in printed.stdout and "install robofailring[vlm]" in printed.stdout


#: Runs the command in a fresh interpreter where no extra's module can be imported.
WITHOUT_EXTRAS = """
import json, sys
for module in sys.argv[1:]:
    sys.modules[module] = None
from typer.testing import CliRunner
from rfr_viz.cli.app import app
runner = CliRunner()
help = runner.invoke(app, ["--help"])
replay = runner.invoke(app, ["replay", "data", "--memory", "memory"])
print(json.dumps({"help": [help.exit_code, help.output], "replay": [replay.exit_code, replay.output],
                  "exception": repr(replay.exception)}))
"""


def test_the_command_starts_without_the_extras_and_a_recording_verb_names_viz() -> None:
    result = subprocess.run(
        [sys.executable, "-c", WITHOUT_EXTRAS, *sorted(EXTRA_MODULES)],
        capture_output=True,
        text=True,
        check=True,
    )
    outcome = json.loads(result.stdout)
    help_code, help_text = outcome["help"]
    assert help_code == 0 and "build-memory" in help_text and "replay" in help_text
    replay_code, replay_text = outcome["replay"]
    assert replay_code == 1, outcome
    assert replay_text.strip().splitlines() == [
        "error: rerun-sdk is not installed; it comes with the viz extra (Rerun recordings and the viewer): "
        'install robofailring[viz] (pip install "robofailring[viz]")'
    ]
