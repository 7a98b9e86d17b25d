"""Outputs are shared like any file the user writes: every atomic write (robofailring.atomic) ends with the
modes the umask gives, though its temporary names are made 0600 (files) and 0700 (folders)."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from fault_helpers import cli
from synthetic import write_aha_dataset

from robofailring.atomic import atomic_directory, atomic_path, write_text_atomic

UMASKS = [(0o022, 0o644, 0o755), (0o027, 0o640, 0o750), (0o002, 0o664, 0o775)]  # umask, file, folder


@contextmanager
def umask(mask: int) -> Iterator[None]:
    previous = os.umask(mask)
    try:
        yield
    finally:
        os.umask(previous)


def mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.mark.parametrize(("mask", "file_mode", "folder_mode"), UMASKS, ids=lambda value: f"{value:03o}")
def test_atomic_files_and_folders_get_the_modes_the_umask_gives(
    tmp_path: Path, mask: int, file_mode: int, folder_mode: int
) -> None:
    with umask(mask):
        write_text_atomic(tmp_path / "table.md", "| a |\n")
        with atomic_path(tmp_path / "run.rrd", suffix=".rrd") as tmp:
            tmp.write_bytes(b"recording")
        for _ in range(2):  # made, then replaced
            with atomic_directory(tmp_path / "memory") as folder:
                (folder / "manifest.json").write_text("{}")
    assert {name: mode(tmp_path / name) for name in ("table.md", "run.rrd", "memory")} == {
        "table.md": file_mode,
        "run.rrd": file_mode,
        "memory": folder_mode,
    }


def test_a_built_memory_is_readable_by_the_group_its_umask_allows(tmp_path: Path) -> None:
    dataset = write_aha_dataset(tmp_path / "data", symbols=("grasp_wp2",), episodes=1, length=3)
    with umask(0o027):
        built = cli("build-memory", dataset, "--out", tmp_path / "memory", "--cache-dir", tmp_path / "cache")
    assert built.exit_code == 0, built.output
    memory = tmp_path / "memory"
    assert mode(memory) == 0o750 and mode(memory / "manifest.json") == 0o640
