"""Fixtures of the CLI fault tests (test_faults.py, test_faults_inputs.py): a tiny dataset, its cache, a memory."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from fault_helpers import cli
from synthetic import write_aha_dataset


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


@pytest.fixture(scope="module")
def built_memory(data: Path, cache: list[str], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The memory `build-memory` makes of `data`, built once per module; tests get copies (`memory`)."""
    out = tmp_path_factory.mktemp("built") / "memory"
    result = cli("build-memory", data, "--out", out, *cache)
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture()
def memory(built_memory: Path, tmp_path: Path) -> Path:
    """A test's own copy of the module's memory, free to damage, replace or grow (a copied memory folder
    is a whole memory: nothing in it names where it lives)."""
    return Path(shutil.copytree(built_memory, tmp_path / "memory"))
