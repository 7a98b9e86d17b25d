"""Helpers for the fault tests: the CLI run in-process, a refusal check, what a write left behind.

Their fixtures (a tiny dataset, its cache and memory) live in tests/cli/conftest.py.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner, Result

from rfr_viz.cli.app import app

runner = CliRunner()


def cli(*args: object) -> Result:
    return runner.invoke(app, [str(arg) for arg in args])


def refused(result: Result, code: int, *phrases: str) -> None:
    """The command ended with `code` and one `error:` line holding every phrase, no traceback."""
    assert result.exit_code == code, result.output
    assert isinstance(result.exception, SystemExit), result.exception
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.output
    for phrase in phrases:
        assert phrase in errors[0], errors[0]


def hidden(folder: Path) -> list[str]:
    """Names a killed or refused write could leave behind (`.<name>.<random>.tmp|old`, `.<name>.lock`)."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


# ---------------------------------------------------------------- a write killed half-way

DIE_ON_REPLACE = """
import os, sys
from pathlib import Path
final = Path(sys.argv[1]).absolute()
real = os.replace
def killed_before_the_new_memory_is_in(src, dst):
    if Path(dst).absolute() == final:  # the old memory is already moved aside
        os._exit(137)
    real(src, dst)
os.replace = killed_before_the_new_memory_is_in
from rfr_viz.cli.app import app
app(sys.argv[2:])
"""

DIE_WHILE_WRITING = """
import os, sys
import faiss
faiss.write_index = lambda *args: os._exit(137)
from rfr_viz.cli.app import app
app(sys.argv[2:])
"""


def killed(script: str, memory: Path, *args: object) -> None:
    command = [sys.executable, "-c", script, str(memory), *map(str, args)]
    env = {**os.environ, "ROBOFAILRING_PROGRESS": "0"}
    assert subprocess.run(command, capture_output=True, env=env, check=False).returncode == 137


# ---------------------------------------------------------------- Ctrl-C, while loading or while writing

SIGINT_WHILE_LOADING = """
import importlib.abc, os, signal, sys
class CtrlC(importlib.abc.MetaPathFinder):  # a Ctrl-C as the command starts loading numpy (its first half second)
    def find_spec(self, name, path=None, target=None):
        if name == "numpy":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None
sys.meta_path.insert(0, CtrlC())
sys.argv[1:] = sys.argv[2:]
from rfr_viz.cli.app import main  # what the console script runs
sys.exit(main())
"""

SIGINT_WHILE_WRITING = """
import os, signal, sys
import faiss
real = faiss.write_index
def ctrl_c(*args):  # a Ctrl-C with the new memory half-written beside the old one
    os.kill(os.getpid(), signal.SIGINT)
    real(*args)
faiss.write_index = ctrl_c
sys.argv[1:] = sys.argv[2:]
from rfr_viz.cli.app import main
sys.exit(main())
"""


SIGTERM_WHILE_WRITING = SIGINT_WHILE_WRITING.replace("signal.SIGINT", "signal.SIGTERM")  # a scheduler's stop


def interrupted(script: str, *args: object) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-c", script, "-", *map(str, args)]
    env = {**os.environ, "ROBOFAILRING_PROGRESS": "0"}
    return subprocess.run(command, capture_output=True, text=True, env=env, check=False)
