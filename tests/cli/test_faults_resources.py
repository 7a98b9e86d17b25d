"""Files of a shared memory or dataset that declare more than they hold, or are no files at all (issue 50):
each is one `error:` line naming the file and status 2, before anything is allocated (each failed before
its fix, with real files: a read until memory ran out, a MemoryError or Rerun's OverflowError traceback)."""

from __future__ import annotations

import io
import json
import os
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli, refused
from synthetic import write_project_dataset

DECLARED = (10**11, 129)  # 103 TB of float64, in a few hundred bytes


def declare_in_npz(path: Path, member: str, shape: tuple[int, ...] = DECLARED) -> None:
    """Rewrite `member` of the `.npz` at `path` as an .npy header declaring `shape`, followed by 16 bytes."""
    with zipfile.ZipFile(path) as archive:
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    assert f"{member}.npy" in members, sorted(members)
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    members[f"{member}.npy"] = header.getvalue() + bytes(16)
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)


@pytest.fixture(scope="module")
def with_signals(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, list[str]]:
    """A project dataset with the robot's signals, and its memory (with `signals.npz`)."""
    root = tmp_path_factory.mktemp("signals")
    data = write_project_dataset(
        root / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=3, signals=True
    )
    cache = ["--cache-dir", str(root / "cache")]
    result = cli("build-memory", data, "--out", root / "memory", "--split", "train", *cache)
    assert result.exit_code == 0, result.output
    assert (root / "memory" / "signals.npz").is_file()
    return data, root / "memory", cache


def _episode(data: Path) -> Path:
    return next(path for path in sorted(data.iterdir()) if "grasp_wp2" in path.name)


def test_a_memory_npz_member_declaring_a_huge_shape_is_refused_before_it_is_allocated(
    with_signals: tuple[Path, Path, list[str]], tmp_path: Path
) -> None:
    data, built, cache = with_signals
    memory = Path(shutil.copytree(built, tmp_path / "memory"))
    declare_in_npz(memory / "signals.npz", "t0_failure")
    said = ("signals.npz: t0_failure declares shape (100000000000, 129), the manifest says (",)
    refused(cli("memory-info", memory), 2, *said)
    refused(cli("detect", _episode(data), "--memory", memory, *cache), 2, *said)


def test_a_deflated_memory_member_of_more_rows_than_the_manifest_says_is_refused_before_it_is_inflated(
    with_signals: tuple[Path, Path, list[str]], tmp_path: Path
) -> None:
    """N5: deflated zeros expand a thousandfold, within what deflate can do, so only the manifest bounds
    them: a member declaring more entries than it says is refused from its header, not once built (the
    reporter's 10 MB file took 1.3 GB before `has 1600000 failure vectors, the manifest says 179`)."""
    data, built, cache = with_signals
    memory = Path(shutil.copytree(built, tmp_path / "memory"))
    manifest = json.loads((memory / "manifest.json").read_text())
    entries = manifest["signals"]["tasks"]["pick_cube"]["failure_entries"]
    with np.load(memory / "signals.npz") as stored:
        arrays = dict(stored)
    width = arrays["t0_failure"].shape[1]
    rows = 20_000
    arrays["t0_failure"] = np.zeros((rows, width), np.float32)  # every member the bomb's size, consistent
    for part in ("episodes", "symbols", "frames"):
        arrays[f"t0_failure_{part}"] = np.resize(arrays[f"t0_failure_{part}"], rows)
    np.savez_compressed(memory / "signals.npz", **arrays)
    said = (
        f"signals.npz: t0_failure declares shape ({rows}, {width}), the manifest says ({entries}, {width})",
    )
    refused(cli("memory-info", memory), 2, *said)
    refused(cli("detect", _episode(data), "--memory", memory, *cache), 2, *said)


def test_a_dataset_npz_member_declaring_a_huge_shape_is_a_signal_not_read(
    with_signals: tuple[Path, Path, list[str]], tmp_path: Path
) -> None:
    """An episode's own signals as the dataset's layout reads them: a file it cannot use is said and the
    episode judged by its cameras (status 3, docs/data.md), not a MemoryError traceback."""
    data, memory, cache = with_signals
    copied = Path(shutil.copytree(data, tmp_path / "data"))
    signals = _episode(copied) / "signals.npz"
    declare_in_npz(signals, "gripper_width")
    result = cli("detect", _episode(copied), "--memory", memory, *cache)
    assert result.exit_code == 3, result.output
    assert f"{signals}: gripper_width declares shape (100000000000, 129)" in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize("kind", ["link to /dev/zero", "FIFO"])
@pytest.mark.parametrize("name", ["entries.jsonl", "success_runs.jsonl", "manifest.json", "index.faiss"])
def test_a_memory_file_that_is_no_regular_file_is_refused_unread(
    with_signals: tuple[Path, Path, list[str]], tmp_path: Path, kind: str, name: str
) -> None:
    """`entries.jsonl` a link to /dev/zero was read until memory ran out; a FIFO was waited on forever."""
    _, built, _ = with_signals
    memory = Path(shutil.copytree(built, tmp_path / "memory"))
    (memory / name).unlink()
    if kind == "FIFO":
        os.mkfifo(memory / name)
    else:
        (memory / name).symlink_to("/dev/zero")
    refused(cli("memory-info", memory), 2, str(memory / name), "is not a regular file")


@pytest.mark.parametrize("verb", ["replay", "watch"])
@pytest.mark.parametrize("fps", [1e-12, 1e300, "fast"])
def test_a_dataset_fps_out_of_range_is_one_line_naming_the_manifest(
    with_signals: tuple[Path, Path, list[str]], tmp_path: Path, verb: str, fps: object
) -> None:
    """`--fps` was checked, the data's own rate not: 1e-12 ended in Rerun's OverflowError (replay) or
    `time.sleep`'s (watch)."""
    data, memory, cache = with_signals
    copied = Path(shutil.copytree(data, tmp_path / "data"))
    manifest = json.loads((copied / "manifest.json").read_text())
    manifest["fps"] = fps
    for record in manifest["episodes"]:
        record.pop("fps", None)
    (copied / "manifest.json").write_text(json.dumps(manifest))
    out = ("--out", tmp_path / "rec") if verb == "replay" else ("--save", tmp_path / "watched.rrd")
    target = copied if verb == "replay" else _episode(copied)
    result = cli(verb, target, "--memory", memory, *out, *cache)
    refused(result, 2, str(copied / "manifest.json"), "fps must be a number of frames per second", repr(fps))
    assert not (tmp_path / "rec").exists() and not (tmp_path / "watched.rrd").exists()


def test_a_dataset_fps_out_of_range_is_refused_where_every_episode_has_its_own(
    with_signals: tuple[Path, Path, list[str]], tmp_path: Path
) -> None:
    """M5: the manifest's top-level `fps` was read only for an episode without its own, so a bad one passed."""
    data, memory, cache = with_signals
    copied = Path(shutil.copytree(data, tmp_path / "data"))
    manifest = json.loads((copied / "manifest.json").read_text())
    manifest["fps"] = "fast"
    for record in manifest["episodes"]:
        record["fps"] = 10
    (copied / "manifest.json").write_text(json.dumps(manifest))
    result = cli("replay", copied, "--memory", memory, "--out", tmp_path / "rec", *cache)
    refused(result, 2, f"{copied / 'manifest.json'}: fps must be a number of frames per second", "'fast'")
    assert not (tmp_path / "rec").exists()
