"""Fixtures shared by the memory tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from robofailring import CachedEncoder, load_encoder


@pytest.fixture()
def encoder(tmp_path: Path) -> CachedEncoder:
    """The weight-free encoder with an embedding cache of the test's own."""
    return CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
