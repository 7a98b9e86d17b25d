"""Shared fixtures: tiny synthetic datasets written as real PNG files."""

from __future__ import annotations

from pathlib import Path

import pytest
from synthetic import write_aha_dataset


@pytest.fixture(scope="session")
def aha_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_aha_dataset(tmp_path_factory.mktemp("aha"))


@pytest.fixture()
def cache_dir(tmp_path: Path) -> Path:
    return tmp_path / "cache"
