"""Random bytes where the CLI expects images, videos, a memory's manifest and a labels file, run as a user would.

Each case is the real CLI (in-process, as `robofailring` runs it) on files of seeded random bytes (the same
bytes every run). It ends in one `error:` line naming the file and status 2, or, where the verb did its work
around the bad input, status 3 with the file named among what was not read; never a traceback: any exception
other than the CLI's own exit is one (tests/cli/test_cli.py runs the installed console script itself).
Crafted files join them (issue 45, item 6): JSON nested past what Python's parser recurses (a manifest,
labels, a trained encoder's config), HDF5 cameras of empty frames, a Faiss index declaring more than it
holds.
"""

from __future__ import annotations

import shutil
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from crafted import GIB_OF_FLOATS, declare_in_index, nested_json
from fault_helpers import cli
from hdf5_writer import write_robomimic

EPISODE = "pick_cube_grasp_wp2_episode0"  # an episode of the `data` fixture (tests/cli/conftest.py)


TEXT = np.frombuffer(
    b'episode_index,outcome,symbol\nsuccess failure grasp_wp2 0123456789"{}[]:;_- ', np.uint8
)
YAML = np.frombuffer(b"symbols:\nstages: knocked_cup 12 &a *a [] {} ? - , ' \" !!str #\n  ", np.uint8)


def random_bytes(
    path: Path, rng: np.random.Generator, *, text: bool = False, alphabet: np.ndarray = TEXT
) -> Path:
    """`path` filled with 1–2,000 random bytes (the generator decides how many); `text`: drawn from
    `alphabet`, by default the characters of a labels file (commas, newlines, its column names), so a
    parser gets past decoding."""
    path.parent.mkdir(parents=True, exist_ok=True)
    size = int(rng.integers(1, 2_000))
    path.write_bytes(rng.choice(alphabet, size).tobytes() if text else rng.bytes(size))
    return path


@dataclass(frozen=True)
class Inputs:
    data: Path  # a copy of the tiny AHA dataset, free to damage
    memory: Path  # a copy of the memory built from it, free to damage
    work: Path  # where a case writes new files and outputs
    rng: np.random.Generator


@pytest.fixture(scope="module")
def built(data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    memory = tmp_path_factory.mktemp("fuzz") / "memory"
    assert cli("build-memory", data, "--out", memory, "--cache-dir", memory.parent / "cache").exit_code == 0
    return memory


def images_in_an_episode(given: Inputs) -> tuple[list[object], Path, int]:
    for image in sorted((given.data / EPISODE).glob("*.png")):
        random_bytes(image, given.rng)
    return ["build-memory", given.data, "--out", given.work / "out"], given.data / EPISODE / "front_0.png", 2


def an_image_beside_the_episodes(given: Inputs) -> tuple[list[object], Path, int]:
    stray = random_bytes(given.data / "front_0.png", given.rng)  # not read: the memory is built, status 3
    return ["build-memory", given.data, "--out", given.work / "out"], stray, 3


def videos_to_detect(given: Inputs) -> tuple[list[object], Path, int]:
    episode = given.work / "videos" / EPISODE
    for view in ("front", "wrist"):
        random_bytes(episode / f"{view}.mp4", given.rng)
    return ["detect", episode, "--memory", given.memory], episode / "front.mp4", 2


def a_manifest_to_read(given: Inputs) -> tuple[list[object], Path, int]:
    manifest = random_bytes(given.memory / "manifest.json", given.rng)
    return ["memory-info", given.memory], manifest, 2  # the one verb here without --cache-dir


def labels_to_build_with(given: Inputs) -> tuple[list[object], Path, int]:
    labels = random_bytes(given.work / "labels.csv", given.rng, text=True)
    return ["build-memory", given.data, "--out", given.work / "out", "--labels", labels], labels, 2


def labels_to_calibrate_with(given: Inputs) -> tuple[list[object], Path, int]:
    labels = random_bytes(given.work / "labels.json", given.rng)
    return ["calibrate", given.data, "--memory", given.memory, "--labels", labels], labels, 2


def a_vocabulary_to_build_with(given: Inputs) -> tuple[list[object], Path, int]:
    words = random_bytes(given.work / "words.yaml", given.rng, text=True, alphabet=YAML)
    return ["build-memory", given.data, "--out", given.work / "out", "--vocabulary", words], words, 2


def an_hdf5_file_to_build_from(given: Inputs) -> tuple[list[object], Path, int]:
    path = random_bytes(given.work / "hdf5" / "demo.hdf5", given.rng)
    return ["build-memory", path, "--out", given.work / "out"], path, 2


def a_png_header_declaring_any_size(given: Inputs) -> tuple[list[object], Path, int]:
    """Each image of an episode declares a random width and height up to 2**31 - 1 (issue 35, item 7)."""
    for image in sorted((given.data / EPISODE).glob("*.png")):
        data = bytearray(image.read_bytes())
        data[16:24] = struct.pack(">II", *(int(n) for n in given.rng.integers(1, 2**31, 2)))
        data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
        image.write_bytes(bytes(data))
    return ["build-memory", given.data, "--out", given.work / "out"], given.data / EPISODE / "front_0.png", 2


def a_deeply_nested_manifest(given: Inputs) -> tuple[list[object], Path, int]:
    """Valid JSON nesting 1,000–200,000 lists or objects, past what Python's parser recurses (issue 45, item 6)."""
    manifest = given.memory / "manifest.json"
    depth = int(given.rng.integers(1_000, 200_000))
    manifest.write_text(nested_json(depth, opener=str(given.rng.choice(["[", "{"]))))
    return ["detect", given.data / EPISODE, "--memory", given.memory], manifest, 2


def deeply_nested_labels(given: Inputs) -> tuple[list[object], Path, int]:
    labels = given.work / "labels.json"
    labels.parent.mkdir(parents=True, exist_ok=True)
    labels.write_text(
        nested_json(int(given.rng.integers(1_000, 200_000)), opener=str(given.rng.choice(["[", "{"])))
    )
    return ["calibrate", given.data, "--memory", given.memory, "--labels", labels], labels, 2


def an_encoder_config_nested_too_deeply(given: Inputs) -> tuple[list[object], Path, int]:
    config = given.work / "encoder" / "encoder.json"
    config.parent.mkdir(parents=True)
    config.write_text(
        nested_json(int(given.rng.integers(1_000, 200_000)), opener=str(given.rng.choice(["[", "{"])))
    )
    return (
        ["build-memory", given.data, "--out", given.work / "out", "--encoder", f"trained:{config.parent}"],
        config,
        2,
    )


def an_hdf5_camera_of_empty_frames(given: Inputs) -> tuple[list[object], Path, int]:
    """A robomimic camera of (6, H, W, 3) frames, H or W (or both) zero (issue 45, item 6)."""
    height, width = (int(n) for n in given.rng.integers(0, 5, 2))
    height, width = (0, width) if given.rng.random() < 0.5 else (height, 0)
    empty = lambda demo, camera, t: np.zeros((height, width, 3), np.uint8)  # noqa: E731
    path = write_robomimic(given.work / "hdf5" / "demo_failed.hdf5", empty, demos=2, length=6)
    return ["build-memory", path, "--out", given.work / "out"], path, 2


def a_faiss_index_declaring_any_size(given: Inputs) -> tuple[list[object], Path, int]:
    """The memory's index.faiss declares 32 GiB to 1 TiB of vectors (past that Faiss refuses on its own),
    maybe more entries than it holds too, in a file of a few KB (issue 45, item 6: Faiss allocated what the
    header said, a std::bad_alloc)."""
    index = given.memory / "index.faiss"
    entries = int(given.rng.integers(2**20, 2**62)) if given.rng.random() < 0.5 else None
    declare_in_index(index, entries=entries, floats=int(given.rng.integers(32 * GIB_OF_FLOATS, 2**38)))
    return ["detect", given.data / EPISODE, "--memory", given.memory], index, 2


CASES: list[Callable[[Inputs], tuple[list[object], Path, int]]] = [
    images_in_an_episode,
    an_image_beside_the_episodes,
    videos_to_detect,
    a_manifest_to_read,
    labels_to_build_with,
    labels_to_calibrate_with,
    a_vocabulary_to_build_with,
    an_hdf5_file_to_build_from,
    a_png_header_declaring_any_size,
    a_deeply_nested_manifest,
    deeply_nested_labels,
    an_encoder_config_nested_too_deeply,
    an_hdf5_camera_of_empty_frames,
    a_faiss_index_declaring_any_size,
]


@pytest.mark.parametrize("case", CASES, ids=[case.__name__ for case in CASES])
def test_random_bytes_end_in_one_error_line_not_a_traceback(
    case: Callable[[Inputs], tuple[list[object], Path, int]], data: Path, built: Path, tmp_path: Path
) -> None:
    given = Inputs(
        data=Path(shutil.copytree(data, tmp_path / "data")),
        memory=Path(shutil.copytree(built, tmp_path / "memory")),
        work=tmp_path / "work",
        rng=np.random.default_rng(CASES.index(case) + 24),  # issue 24: the same bytes every run
    )
    args, bad_file, status = case(given)
    cache = [] if args[0] == "memory-info" else ["--cache-dir", tmp_path / "cache"]
    result = cli(*args, *cache)
    assert isinstance(result.exception, SystemExit), (result.exception, result.output)  # else a traceback
    assert result.exit_code == status, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    if status == 2:
        assert len(errors) == 1 and str(bad_file) in errors[0], result.output
    else:  # done around the bad input: nothing failed, and the file is named among what was not read
        assert errors == [] and f"  {bad_file}: " in result.output, result.output
