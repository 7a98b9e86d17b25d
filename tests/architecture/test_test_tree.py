"""The test tree itself: pytest's default import mode needs each test module's basename once."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]


def test_no_two_test_modules_share_a_basename() -> None:
    names = Counter(path.name for path in TESTS.rglob("test_*.py"))
    assert len(names) > 40  # the tree was found
    assert [name for name, count in names.items() if count > 1] == []


def test_fixture_modules_are_not_loaded_per_test_module() -> None:
    """`pytest_plugins` in a test module registers its fixtures for every module: a conftest.py holds them."""
    loading = [
        str(path.relative_to(TESTS))
        for path in TESTS.rglob("test_*.py")
        if re.search(r"^pytest_plugins\b", path.read_text(), re.MULTILINE)
    ]
    assert loading == []
