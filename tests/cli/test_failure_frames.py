"""`--failure-frames end|dense` from the command line: the memory built says which, a bad value is one usage
error naming the choices, and a memory grows only in its own kind."""

from __future__ import annotations

import json
from pathlib import Path

from fault_helpers import cli, refused

from robofailring import FailureMemory


def test_build_memory_builds_either_kind_and_says_which(data: Path, cache: list[str], tmp_path: Path) -> None:
    end = cli("build-memory", data, "--out", tmp_path / "end", "--failure-frames", "end", *cache)
    assert end.exit_code == 0, end.output
    assert "failure memory: end (the paper's), 12 entries from 12 failure views" in end.output
    assert json.loads((tmp_path / "end" / "manifest.json").read_text())["failure_frames"] == "end"

    dense = cli("build-memory", data, "--out", tmp_path / "dense", *cache)  # the default
    assert dense.exit_code == 0, dense.output
    assert "failure memory: dense, 24 entries from 12 failure views" in dense.output  # frames 1 and 2 of 3
    memory = FailureMemory.load(tmp_path / "dense")
    assert memory.manifest.failure_mode == "dense" and {(e.frame, e.length) for e in memory.entries} == {
        (1, 3),
        (2, 3),
    }
    info = cli("memory-info", tmp_path / "dense")
    assert info.exit_code == 0 and "failures    dense, 24 entries from 12 failure views" in info.output


def test_a_bad_value_is_a_usage_error_naming_the_choices(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    for verb in (
        ("build-memory", data, "--out", tmp_path / "memory"),
        ("evaluate", data, "--out", tmp_path / "evaluation"),
    ):
        refused(
            cli(*verb, "--failure-frames", "last", *cache),
            2,
            "failure frames must be end or dense, got 'last'",
        )
    assert not (tmp_path / "memory").exists() and not (tmp_path / "evaluation").exists()


def test_add_to_keeps_the_memorys_kind(data: Path, cache: list[str], tmp_path: Path) -> None:
    memory = tmp_path / "memory"
    built = cli("build-memory", data, "--out", memory, "--failure-frames", "end", *cache)
    assert built.exit_code == 0, built.output
    before = (memory / "manifest.json").read_text()
    refused(
        cli("build-memory", data, "--add-to", memory, "--failure-frames", "dense", *cache),
        2,
        "--failure-frames dense differs from the memory",
        "which holds end failure frames",
    )
    assert (memory / "manifest.json").read_text() == before
