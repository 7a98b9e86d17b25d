"""Outputs as users lay them out (issue 35, item 9): a symlinked --out, a folder of theirs beside it
named like a leftover, and a refused command that must leave no empty folder behind."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from fault_helpers import cli, refused

from robofailring.memory.entry import MemoryEntry
from robofailring.memory.failure import FailureMemory
from robofailring.memory.stored_calibration import StoredCalibration, StoredRule


def _memory(count: int) -> FailureMemory:
    entries = [
        MemoryEntry(task="t", symbol="slip_wp3", episode=f"e{i}", view="front", start="a.png", end="b.png")
        for i in range(count)
    ]
    return FailureMemory(np.eye(count, 8, dtype=np.float32), entries, encoder="pixels-32")


def test_a_memory_behind_a_symbolic_link_is_replaced_where_the_link_points(tmp_path: Path) -> None:
    real = tmp_path / "store" / "memory"
    _memory(2).save(real)
    link = tmp_path / "current"
    link.symlink_to(real, target_is_directory=True)
    _memory(3).save(link)
    assert link.is_symlink() and link.resolve() == real.resolve()  # still the user's link
    assert len(FailureMemory.load(link)) == len(FailureMemory.load(real)) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["current", "store"]  # no `.current.*.old` left
    assert sorted(p.name for p in real.parent.iterdir()) == ["memory"]
    loaded = FailureMemory.load(link)  # calibrating through the link writes the manifest at the target
    loaded.with_calibration(
        StoredCalibration(rules={"paper": StoredRule(threshold=0.5)}, encoder="pixels-32")
    ).write_manifest(link)
    assert FailureMemory.load(real).calibrated_threshold("paper") == 0.5 and link.is_symlink()


def test_a_users_folder_named_like_a_leftover_is_never_removed(tmp_path: Path) -> None:
    mine = tmp_path / ".memory.abcd1234.tmp"  # the pattern of the project's own temporary names before
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    theirs_too = tmp_path / ".memory.x.old"
    theirs_too.write_text("also mine")
    _memory(2).save(tmp_path / "memory")
    _memory(3).save(tmp_path / "memory")  # a replace cleans leftovers: only its own `rfr-` names
    assert (mine / "notes.txt").read_text() == "mine" and theirs_too.read_text() == "also mine"
    leftover = tmp_path / ".memory.rfr-abcd1234.tmp"  # what a killed write of this version leaves
    leftover.mkdir()
    _memory(4).save(tmp_path / "memory")
    assert not leftover.exists() and mine.is_dir()


def test_a_refused_replay_or_evaluate_leaves_no_empty_output_folder(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    missing = tmp_path / "no-memory"
    out = tmp_path / "new" / "recordings"
    refused(cli("replay", data, "--memory", missing, "--out", out, *cache), 2, str(missing))
    assert not out.exists() and not out.parent.exists()
    blocked = tmp_path / "a-file"
    blocked.write_text("x")
    refused(
        cli("replay", data, "--memory", missing, "--out", blocked / "sub", *cache),
        2,
        "part of that path is a file",
    )


def test_a_folder_option_naming_a_file_says_which_option_and_what_it_holds(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    """`demo --data-dir FILE` said `error: File exists: FILE` (status 1), as `generate` and `train-encoder`
    did for an --out under a file: each now names its option, the path and what the folder holds, before any
    work (nothing simulated, nothing written)."""
    a_file = tmp_path / "notes.txt"
    a_file.write_text("mine")
    out = tmp_path / "demo"
    for given, where in ((a_file, "is a file"), (a_file / "sub", f"part of that path is a file ({a_file})")):
        refused(
            cli("demo", "--data-dir", given, "--out", out, *cache),
            2,
            f"--data-dir {given} {where}" if given == a_file else f"--data-dir {given} cannot be made",
            where,
            "the demo's cache of simulated datasets is a folder: choose another --data-dir",
        )
        refused(
            cli("generate", "--out", given), 2, f"--out {given}", where, "a generated dataset is a folder"
        )
        refused(
            cli("train-encoder", data, "--out", given),
            2,
            f"--out {given}",
            where,
            "a trained encoder",
        )
        refused(cli("evaluate", data, "--out", given, *cache), 2, f"--out {given}", where, "this output")
        refused(cli("build-memory", data, "--out", given, *cache), 2, f"--out {given}", where, "a memory")
    assert not out.exists() and a_file.read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
