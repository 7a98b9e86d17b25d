"""The test tree itself: each test module's basename once (pytest's default import mode), fixtures registered in a
conftest.py, and a missing requirement asked for through tests/environment.py (a failure in the full lane)."""

from __future__ import annotations

import json
import re
from collections import Counter
from pathlib import Path

import pytest
from environment import FULL_ENV, require_module

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


def test_a_missing_module_is_asked_for_through_the_environment_helper() -> None:
    """pytest.importorskip skips in the full lane too: `environment.require_module` fails there instead."""
    skipping = [
        str(path.relative_to(TESTS))
        for path in TESTS.rglob("*.py")
        if "importorskip(" in path.read_text() and path.name != "test_test_tree.py"
    ]
    assert skipping == []


#: Tests that skip where they do not apply, which no install changes (not a missing piece of the full lane).
SKIPS_WITHOUT_A_MISSING_PIECE = {"encoders/test_exported.py": 1}  # ONNX Runtime with CUDA: nothing to say


def test_a_missing_piece_is_asked_for_through_the_environment_helper_not_skipped() -> None:
    """A test that lacks a venv, a file or a tool calls `environment.missing` (a failure in the full lane);
    a bare pytest.skip skipped there too (tests/docs/test_benches.py's peer venv did, issue 50)."""
    skipping = {
        str(path.relative_to(TESTS)): count
        for path in TESTS.rglob("*.py")
        if path.name not in ("environment.py", "test_test_tree.py")
        and (count := len(re.findall(r"\bpytest\.skip\(", path.read_text())))
    }
    assert skipping == SKIPS_WITHOUT_A_MISSING_PIECE


def test_a_missing_requirement_fails_the_full_lane_and_skips_a_plain_run(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setenv(FULL_ENV, "1")
    with pytest.raises(
        pytest.fail.Exception, match=r"robofailring_absent cannot be imported .*: pip install it"
    ):
        require_module("robofailring_absent", "pip install it")
    monkeypatch.delenv(FULL_ENV)
    with pytest.raises(pytest.skip.Exception, match="robofailring_absent cannot be imported"):
        require_module("robofailring_absent", "pip install it")
    assert require_module("json", "") is json
