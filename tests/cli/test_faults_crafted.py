"""Crafted inputs through the CLI (issue 45, item 6): each ends in one `error:` line naming the file or
value and status 2, never a traceback (each failed so before its fix, with real files)."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from crafted import GIB_OF_FLOATS, declare_in_index, nested_json
from fault_helpers import cli, refused
from hdf5_writer import write_aloha, write_robomimic
from synthetic import write_project_dataset

from robofailring.data.images import as_rgb
from robofailring.errors import DataError

EPISODE = "pick_cube_grasp_wp2_episode0"  # an episode of the `data` fixture (tests/cli/conftest.py)


@pytest.mark.parametrize("opener", ["[", "{"])
def test_deeply_nested_json_is_one_error_line_wherever_it_is_read(
    memory: Path, data: Path, cache: list[str], tmp_path: Path, opener: str
) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text(nested_json(opener=opener))
    too_deep = "nests lists or objects too deeply"
    for verb in ("build-memory", "calibrate"):
        target = ("--out", tmp_path / "out") if verb == "build-memory" else ("--memory", memory)
        refused(cli(verb, data, *target, "--labels", deep, *cache), 2, f"labels file {deep}", too_deep)
    assert not (tmp_path / "out").exists()
    vlm = ("--vlm-url", "http://127.0.0.1:9/v1", "--vlm-model", "m")  # never asked: the file is refused first
    refused(cli("explain", deep, *vlm), 2, str(deep), too_deep)
    refused(cli("review", deep, "--data", data, "--out", tmp_path / "rev", *cache), 2, str(deep), too_deep)
    assert not (tmp_path / "rev").exists()
    manifest = memory / "manifest.json"
    manifest.write_text(nested_json(opener=opener))
    refused(cli("memory-info", memory), 2, str(manifest), too_deep)
    refused(cli("detect", data / EPISODE, "--memory", memory, *cache), 2, str(manifest), too_deep)


def test_a_deeply_nested_entries_line_is_named_with_its_line(
    memory: Path, data: Path, cache: list[str]
) -> None:
    entries = memory / "entries.jsonl"
    lines = entries.read_text().splitlines()
    entries.write_text("\n".join([lines[0], nested_json(), *lines[2:]]) + "\n")
    refused(cli("detect", data / EPISODE, "--memory", memory, *cache), 2, f"{entries}:2", "too deeply")


@pytest.mark.parametrize("shape", [(0, 32), (32, 0)])
def test_hdf5_cameras_of_empty_frames_are_one_error_line_naming_file_and_dataset(
    cache: list[str], tmp_path: Path, shape: tuple[int, int]
) -> None:
    """A camera of shape (6, 0, 32, 3) ended in OpenCV's `!ssize.empty()` assertion, status 1."""
    empty = lambda episode, camera, t: np.zeros((*shape, 3), np.uint8)  # noqa: E731
    robomimic = write_robomimic(tmp_path / "rm" / "demo_failed.hdf5", empty, demos=2, length=6)
    aloha = write_aloha(tmp_path / "aloha", empty, episodes=2, length=6)
    labels = tmp_path / "labels.csv"
    labels.write_text("episode,outcome,symbol\nepisode_0,failure,grasp_wp2\nepisode_1,success,\n")
    for data, options, camera in (
        (robomimic, (), f"{robomimic}#/data/demo_0/obs/agentview_image"),
        (aloha, ("--labels", labels), f"{aloha / 'episode_0.hdf5'}#/observations/images/cam_high"),
    ):
        out = tmp_path / "memory"
        refused(cli("build-memory", data, "--out", out, *options, *cache), 2, camera, "empty")
        assert not out.exists()
    with pytest.raises(DataError, match=r"live view: an image of shape .* is empty"):
        as_rgb(np.zeros((*shape, 3), np.uint8), source="live view")  # the step API's frames


@pytest.mark.parametrize(
    ("verb", "option", "value"),
    [
        ("replay", "--fps", "1e-300"),  # frame 1 at 1e300 s: an OverflowError writing the recording
        ("replay", "--fps", "1e-10"),
        ("replay", "--fps", "1e300"),
        ("watch", "--fps", "1e-300"),
        ("watch", "--speed", "nan"),  # was accepted: played as fast as it could
        ("watch", "--speed", "inf"),
    ],
)
def test_an_fps_or_speed_out_of_range_is_one_error_line_naming_it(
    memory: Path, data: Path, cache: list[str], tmp_path: Path, verb: str, option: str, value: str
) -> None:
    out = ("--out", tmp_path / "rec") if verb == "replay" else ("--save", tmp_path / "watched.rrd")
    result = cli(verb, data / EPISODE, "--memory", memory, *out, option, value, *cache)
    refused(result, 2, f"{option} must be", f"got {float(value)}")
    assert list(tmp_path.iterdir()) == [memory]


@pytest.fixture(scope="module")
def with_successes(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, list[str]]:
    """A project dataset, and the memory of its training split: a failure and a success memory, one
    flat index file each (`index.faiss`, `success.0.faiss`)."""
    root = tmp_path_factory.mktemp("indexes")
    data = write_project_dataset(
        root / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=3
    )
    cache = ["--cache-dir", str(root / "cache")]
    result = cli("build-memory", data, "--out", root / "memory", "--split", "train", *cache)
    assert result.exit_code == 0, result.output
    assert (root / "memory" / "success.0.faiss").is_file()
    return data, root / "memory", cache


def _truncated(path: Path) -> Path:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    return path


@pytest.mark.parametrize("name", ["index.faiss", "success.0.faiss"])
@pytest.mark.parametrize(
    ("craft", "phrase"),
    [  # each: 50 GiB allocated before reading (std::bad_alloc, a MemoryError traceback), or a Faiss error
        (lambda path: declare_in_index(path, floats=50 * GIB_OF_FLOATS), "53,687,091,200 bytes of vectors"),
        (lambda path: declare_in_index(path, entries=2**40), "declares 1099511627776 entries"),
        (_truncated, "bytes hold"),
    ],
    ids=["50-GiB-of-vectors", "2**40-entries", "truncated"],
)
def test_an_index_file_declaring_more_than_it_holds_is_one_error_line(
    with_successes: tuple[Path, Path, list[str]],
    tmp_path: Path,
    name: str,
    craft: Callable[[Path], Path],
    phrase: str,
) -> None:
    data, built, cache = with_successes
    memory = Path(shutil.copytree(built, tmp_path / "memory"))
    index = craft(memory / name)
    episode = next(p for p in sorted(data.iterdir()) if "grasp_wp2" in p.name)
    for args in (("memory-info", memory), ("detect", episode, "--memory", memory, *cache)):
        refused(cli(*args), 2, str(index), phrase)
