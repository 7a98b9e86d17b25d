"""Bad inputs, end to end through the CLI (issue 13): malformed memories, a broken or stale cache, unclear messages.

Each case was reproduced against the code before its fix, with real files.
"""

from __future__ import annotations

import gc
import json
import os
import sqlite3
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from fault_helpers import cli, hidden, refused
from hdf5_writer import write_aloha, write_robomimic
from synthetic import synthetic_frame, write_episode


def test_malformed_memory_content_is_named(memory: Path, data: Path, cache: list[str]) -> None:
    episode = data / "pick_cube_grasp_wp2_episode0"
    manifest_path, entries_path = memory / "manifest.json", memory / "entries.jsonl"
    manifest, entries = manifest_path.read_text(), entries_path.read_text()
    manifest_path.write_text("[1, 2]")
    refused(cli("detect", episode, "--memory", memory, *cache), 2, "manifest.json")
    manifest_path.write_text(json.dumps({**json.loads(manifest), "calibration": "0.9"}))
    refused(cli("detect", episode, "--memory", memory, *cache), 2, "'calibration' must be an object")
    manifest_path.write_text(manifest)
    lines = entries.splitlines()
    lines[0] = json.dumps({**json.loads(lines[0]), "symbol": "teleport_wp2"})
    entries_path.write_text("\n".join(lines) + "\n")
    refused(cli("detect", episode, "--memory", memory, *cache), 2, "entries.jsonl:1", "teleport")


def test_open_refuses_a_file_that_is_not_a_recording(tmp_path: Path) -> None:
    notes = tmp_path / "notes.rrd"
    notes.write_text("not a recording")
    refused(cli("open", notes), 2, "is not a Rerun recording")


# ---------------------------------------------------------------- the embedding cache


def _bmp_episode(folder: Path, length: int = 3) -> Path:
    folder.mkdir(parents=True)
    for view, v in (("front", 0), ("wrist", 2)):
        for t in range(length):
            image = synthetic_frame("pick_cube", "grasp_wp2", v, t, length)
            cv2.imwrite(str(folder / f"{view}_{t}.bmp"), image[:, :, ::-1])
    return folder


def test_the_cache_sees_an_image_rewritten_with_the_same_size_and_time(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    episode = _bmp_episode(tmp_path / "pick_cube_grasp_wp2_episode7")

    def front() -> list[float]:
        result = cli("detect", episode, "--memory", memory, "--json", *cache)
        assert result.exit_code == 0, result.output
        return list(json.loads(result.stdout)["views"]["front"]["similarity"])

    before = front()
    last = episode / "front_2.bmp"
    stat = last.stat()
    cv2.imwrite(
        str(last), synthetic_frame("pick_cube", None, 1, 0, 3)[:, :, ::-1]
    )  # another scene, same size
    os.utime(last, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert last.stat().st_size == stat.st_size and last.stat().st_mtime_ns == stat.st_mtime_ns
    after = front()
    assert after[:2] == before[:2] and after[2] != before[2]


def test_a_broken_cache_warns_once_and_is_rebuilt_or_skipped(
    memory: Path, data: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    episode = data / "pick_cube_grasp_wp2_episode0"
    expected = cli("detect", episode, "--memory", memory, "--json", "--cache-dir", tmp_path / "plain").stdout

    def detect(cache_dir: Path) -> list[str]:
        caplog.clear()
        result = cli("detect", episode, "--memory", memory, "--json", "--cache-dir", cache_dir)
        assert result.exit_code == 0 and result.stdout == expected, result.output
        return [  # the memory is not calibrated: that is said too, and not about the cache
            record.getMessage()
            for record in caplog.records
            if record.name == "robofailring" and "not calibrated" not in record.getMessage()
        ]

    a_file = tmp_path / "cache-file"
    a_file.write_text("mine")
    warned = detect(a_file)
    assert len(warned) == 1 and "running without it" in warned[0] and a_file.read_text() == "mine"

    corrupt = tmp_path / "corrupt"
    assert detect(corrupt) == []
    gc.collect()  # close the first run's connection, as the end of its process would
    (database,) = corrupt.glob("embeddings-*.sqlite")
    for side in corrupt.glob("embeddings-*.sqlite-*"):
        side.unlink()
    database.write_bytes(b"this is not a SQLite database" * 100)
    warned = detect(corrupt)
    assert len(warned) == 1 and "is corrupt" in warned[0] and "rebuilding" in warned[0]
    with sqlite3.connect(database) as db:
        assert db.execute("SELECT COUNT(*) FROM emb").fetchone()[0] > 0  # rebuilt and filled again
    assert detect(corrupt) == []

    blocked = tmp_path / "blocked"
    blocked.mkdir()
    (blocked / database.name).mkdir()  # the database's name is taken by a folder: unusable
    warned = detect(blocked)
    assert len(warned) == 1 and "running without it" in warned[0]


# ---------------------------------------------------------------- messages that say what to do


def test_unclear_messages_now_name_the_value(
    memory: Path, data: Path, cache: list[str], tmp_path: Path
) -> None:
    unknown = write_episode(
        tmp_path / "pick_cube_teleport_wp2_episode0", "pick_cube", "grasp_wp2", length=3, layout="aha"
    )
    refused(cli("detect", unknown, "--memory", memory, *cache), 2, "unknown failure type 'teleport'")
    result = cli("detect", data, "--memory", memory, *cache)
    refused(result, 2, "pass one of its episode folders", "robofailring replay")
    # the option it suggests is one detect really has
    assert "--trajectory" in result.output and "--trajectory" in cli("detect", "--help").output
    refused(cli("generate", "--out", tmp_path / "gen", "--episodes", "-1"), 2, "--episodes", "got -1")
    refused(cli("generate", "--out", tmp_path / "gen", "--image-size", "8"), 2, "--image-size", "got 8")


def test_a_junk_checkpoint_is_named(
    memory: Path, cache: list[str], tmp_path: Path, tiny_checkpoint: tuple[Path, Path]
) -> None:
    episode = write_episode(
        tmp_path / "pick_cube_grasp_wp2_episode0", "pick_cube", "grasp_wp2", length=3, layout="aha"
    )
    config, _ = tiny_checkpoint
    junk = tmp_path / "junk.pt"
    junk.write_bytes(np.random.default_rng(0).bytes(1000))
    refused(
        cli(
            "detect",
            episode,
            "--memory",
            memory,
            *cache,
            "--encoder",
            f"open_clip:{config}:{junk}",
        ),
        2,
        str(junk),
        "not a PyTorch state dict",
    )


# ---------------------------------------------------------------- tracebacks of issue 35, item 6


def corrupt_object_header(path: Path, name: str) -> Path:
    """Overwrite the version byte of the object header of `name` (h5py then raises a KeyError opening it)."""
    with h5py.File(path, "r") as handle:
        address = h5py.h5o.get_info(handle[name].id).addr
    raw = bytearray(path.read_bytes())
    raw[address] = 77
    path.write_bytes(bytes(raw))
    return path


@pytest.mark.parametrize(
    "damaged", ["/observations/images/cam_high", "/observations/images", "/observations"]
)
def test_a_corrupt_hdf5_object_header_is_one_error_line(
    memory: Path, cache: list[str], tmp_path: Path, damaged: str
) -> None:
    folder = write_aloha(
        tmp_path / "pick_cube",
        lambda e, c, t: synthetic_frame("pick_cube", None, c, t, 3, size=32),
        episodes=1,
        length=3,
    )
    episode = corrupt_object_header(folder / "episode_0.hdf5", damaged)
    result = cli("detect", episode, "--memory", memory, *cache)
    refused(result, 2, f"cannot read HDF5 file {episode}", "bad object header version number")


def test_a_corrupt_object_header_in_a_robomimic_file_is_named(cache: list[str], tmp_path: Path) -> None:
    frames = lambda demo, camera, t: synthetic_frame("pick_cube", None, camera, t, 3, size=32)  # noqa: E731
    for number, damaged in enumerate(("/data/demo_0", "/data/demo_0/obs/agentview_image", "/data")):
        path = write_robomimic(tmp_path / f"rm{number}" / "demo_failed.hdf5", frames, demos=2, length=3)
        corrupt_object_header(path, damaged)
        out = tmp_path / "memory"
        refused(cli("build-memory", path, "--out", out, *cache), 2, f"cannot read HDF5 file {path}")
        assert not out.exists() and hidden(tmp_path) == []


@pytest.mark.parametrize(
    ("text", "phrases"),
    [
        ("symbols:\n  [knocked, cup]: the gripper knocking the cup over\n", ["line 2", "['knocked', 'cup']"]),
        ("? [knocked]\n: the cup\n", ["line 1", "a key is ['knocked']"]),
        ("symbols:\n  knocked_cup: words\nstages:\n  {1: 2}: approach\n", ["line 4", "a key is {1: 2}"]),
        (  # a billion laughs: 9**8 words from eight lines; refused at the first alias, before any expands
            "symbols:\n  a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n"
            + "".join(
                f"  {k}: &{k} [{', '.join([f'*{p}'] * 9)}]\n"
                for p, k in zip("abcdefg", "bcdefgh", strict=True)
            ),
            ["line 3", "YAML alias *a is not allowed"],
        ),
        ("symbols: " + "[" * 20_000 + "]" * 20_000 + "\n", ["nests lists or objects too deeply"]),
    ],
)
def test_a_vocabulary_with_list_keys_aliases_or_deep_nesting_is_one_error_line(
    data: Path, cache: list[str], tmp_path: Path, text: str, phrases: list[str]
) -> None:
    words = tmp_path / "words.yaml"
    words.write_text(text)
    out = tmp_path / "memory"
    refused(
        cli("build-memory", data, "--out", out, "--vocabulary", words, *cache),
        2,
        f"vocabulary file {words}",
        *phrases,
    )
    assert not out.exists()


def test_a_stride_beyond_any_frame_number_is_refused_and_the_largest_one_scores_frame_0(
    memory: Path, data: Path, cache: list[str]
) -> None:
    episode = data / "pick_cube_grasp_wp2_episode0"
    for verb in ("detect", "replay"):
        refused(
            cli(verb, episode, "--memory", memory, "--stride", "99999999999999999999", *cache),
            2,
            "stride must be a whole number from 1",
            "got 99999999999999999999",
        )
    result = cli("detect", episode, "--memory", memory, "--stride", str(2**63 - 1), "--json", *cache)
    assert result.exit_code == 0, result.output
    trace = json.loads(result.stdout)
    assert trace["stride"] == 2**63 - 1
    assert [value is None for value in trace["views"]["front"]["similarity"]] == [False, True, True]  # NaN
    said = cli("detect", episode, "--memory", memory, "--stride", "2", *cache)
    assert said.exit_code == 0 and "one frame in 2 scored" in said.output  # not "every 2th frame"
