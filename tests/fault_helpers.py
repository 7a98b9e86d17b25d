"""Helpers for the fault tests: the CLI run in-process, a refusal check, a tiny dataset and memory."""

from __future__ import annotations

from pathlib import Path

import pytest
from synthetic import write_aha_dataset
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


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_aha_dataset(
        tmp_path_factory.mktemp("faults") / "data",
        symbols=("grasp_wp2", "wrong_object"),
        episodes=1,
        length=3,
    )


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    return ["--cache-dir", str(tmp_path_factory.mktemp("cache"))]


@pytest.fixture()
def memory(data: Path, cache: list[str], tmp_path: Path) -> Path:
    out = tmp_path / "memory"
    result = cli("build-memory", data, "--out", out, *cache)
    assert result.exit_code == 0, result.output
    return out
