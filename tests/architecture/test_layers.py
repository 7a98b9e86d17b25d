"""The architecture is a contract: import-linter checks the layers in pyproject.toml, and a planted
upward import breaks it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def _lint(tree: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": f"{tree / 'src'}{os.pathsep}{tree}"}
    return subprocess.run(
        [str(LINT_IMPORTS), "--config", str(tree / "pyproject.toml"), "--no-cache"],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )


def _copy_tree(tmp_path: Path) -> Path:
    tree = tmp_path / "tree"
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info")
    shutil.copytree(ROOT / "src" / "robofailring", tree / "src" / "robofailring", ignore=ignore)
    shutil.copytree(ROOT / "rfr_viz", tree / "rfr_viz", ignore=ignore)
    shutil.copy(ROOT / "pyproject.toml", tree / "pyproject.toml")
    return tree


def test_the_layer_contracts_hold(tmp_path: Path) -> None:
    result = _lint(_copy_tree(tmp_path))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "4 kept, 0 broken" in result.stdout


def test_a_planted_upward_import_breaks_the_layers(tmp_path: Path) -> None:
    tree = _copy_tree(tmp_path)
    index = tree / "src" / "robofailring" / "memory" / "index.py"
    index.write_text(index.read_text() + "\nfrom robofailring.evaluation import metrics as _upward  # noqa\n")
    viz_paths = tree / "rfr_viz" / "paths.py"
    viz_paths.write_text(viz_paths.read_text() + "\nimport rfr_viz.jobs.replay as _upward  # noqa\n")
    library = tree / "src" / "robofailring" / "data" / "model.py"
    library.write_text(library.read_text() + "\nimport rerun as _rerun  # noqa\n")
    result = _lint(tree)
    assert result.returncode != 0
    assert "robofailring.memory is not allowed to import robofailring.evaluation" in result.stdout
    assert "rfr_viz.paths is not allowed to import rfr_viz.jobs" in result.stdout
    assert "robofailring.data.model -> rerun" in result.stdout
