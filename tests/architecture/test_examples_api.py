"""The examples (scripts, the notebook, and the Python blocks of README.md and docs/*.md) use only the
curated API: names of `robofailring.__all__` and `rfr_viz.__all__`, imported from the two packages
themselves, never from a module inside them."""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import rfr_viz
import robofailring

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
PUBLIC = {"robofailring": set(robofailring.__all__), "rfr_viz": set(rfr_viz.__all__)}


def _sources() -> dict[str, str]:
    """Each example's code: a script's text, a notebook's code cells joined (as the kernel runs them)."""
    found = {path.name: path.read_text() for path in sorted(EXAMPLES.glob("*.py"))}
    for path in sorted(EXAMPLES.glob("*.ipynb")):
        cells = json.loads(path.read_text())["cells"]
        found[path.name] = "\n\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        blocks = re.findall(r"^```python\n(.*?)^```", page.read_text(), re.MULTILINE | re.DOTALL)
        found |= {f"{page.name} block {i}": block for i, block in enumerate(blocks, 1)}
    return found


def _private_uses(source: str) -> list[str]:
    """Imports from inside the packages, and names not in their `__all__` (imported or `alias.name`)."""
    tree = ast.parse(source)
    aliases: dict[str, str] = {}  # a name bound to one of the packages -> that package
    wrong = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                top = alias.name.split(".")[0]
                if top in PUBLIC:
                    if alias.name != top:
                        wrong.append(f"import {alias.name}")
                    aliases[alias.asname or top] = top
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in PUBLIC:
            if node.module not in PUBLIC:
                wrong.append(f"from {node.module} import …")
                continue
            wrong += [f"{node.module}.{a.name}" for a in node.names if a.name not in PUBLIC[node.module]]
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            package = aliases[node.value.id]
            if node.attr not in PUBLIC[package]:
                wrong.append(f"{package}.{node.attr}")
    return wrong


def test_examples_use_only_the_curated_api() -> None:
    sources = _sources()
    assert {"notebook.ipynb", "closed_loop_sim.py", "build_memory_from_aha.py", "README.md block 1"} <= set(
        sources
    )
    assert {name: _private_uses(source) for name, source in sources.items()} == {name: [] for name in sources}


def test_the_check_finds_private_uses() -> None:
    source = (
        "import robofailring as rfr\nimport rfr_viz\nfrom rfr_viz.recordings.replay import record_replay\n"
        "from robofailring import open_detector, atomic\nrfr.open_detector\nrfr.evaluation\nrfr_viz.show\n"
    )
    assert _private_uses(source) == [
        "from rfr_viz.recordings.replay import …",
        "robofailring.atomic",
        "robofailring.evaluation",
    ]


def test_the_notebook_is_stored_without_outputs() -> None:
    """A run's outputs (widget state, paths of the machine it ran on) stay out of the repository."""
    notebook = json.loads((EXAMPLES / "notebook.ipynb").read_text())
    code = [cell for cell in notebook["cells"] if cell["cell_type"] == "code"]
    assert code and all(cell["outputs"] == [] and cell["execution_count"] is None for cell in code)
    assert "widgets" not in notebook["metadata"]
    assert notebook["metadata"]["kernelspec"]["name"] == "python3"
