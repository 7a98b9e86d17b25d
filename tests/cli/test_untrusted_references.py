"""References read from a shared memory or dataset stay inside their own root (issue 45, item 1): an
edited `entries.jsonl` or `manifest.json` cannot make a verb read, record or send another file of yours."""

from __future__ import annotations

import base64
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli, refused
from rrd import blobs, every_text
from synthetic import write_project_dataset
from vlm_server import chat_server

from robofailring import FailureMemory, load_dataset
from robofailring.data.images import encode_jpeg


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("refs") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=2,
        length=4,
    )


@pytest.mark.parametrize("where", ["absolute", "parent", "sibling"])
def test_an_entry_pointing_outside_the_data_root_is_refused(
    data: Path, cache: list[str], tmp_path: Path, where: str
) -> None:
    """`sibling`: a folder beside the data root whose name starts with the root's (`/x/data-private` beside
    `/x/data`) is outside it, though its path starts with the root's as a string."""
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, *cache).exit_code == 0
    private = tmp_path / "private.png"
    if where == "sibling":
        private = data.parent / f"{data.name}-private" / "private.png"
        private.parent.mkdir(exist_ok=True)
    shutil.copy(next(data.glob("*/front_0.png")), private)
    lines = (memory / "entries.jsonl").read_text().splitlines()
    entry = json.loads(lines[0])
    entry["start"] = {
        "absolute": str(private),
        "parent": "../../private.png",
        "sibling": f"../{data.name}-private/private.png",
    }[where]
    (memory / "entries.jsonl").write_text("\n".join([json.dumps(entry), *lines[1:]]) + "\n")
    out = tmp_path / "recordings"
    result = cli("replay", data, "--memory", memory, "--out", out, *cache)
    refused(result, 2, "lies outside the memory's data root", "refused")
    assert not out.exists() or not list(out.glob("*.rrd"))  # nothing recorded with the private file


def test_a_manifest_dir_outside_the_dataset_is_refused(data: Path, tmp_path: Path) -> None:
    copy = Path(shutil.copytree(data, tmp_path / "data"))
    manifest = json.loads((copy / "manifest.json").read_text())
    elsewhere = Path(shutil.copytree(copy / manifest["episodes"][0]["dir"], tmp_path / "elsewhere"))
    # beside the dataset, named as it is and more: its path starts with the dataset's as a string
    shutil.copytree(elsewhere, tmp_path / "data-private")
    for bad in ("../elsewhere", str(elsewhere), "../data-private", str(tmp_path / "data-private")):
        manifest["episodes"][0]["dir"] = bad
        (copy / "manifest.json").write_text(json.dumps(manifest))
        with pytest.raises(Exception, match="which is not a folder inside the dataset"):
            load_dataset(copy)


def test_runs_added_from_another_dataset_are_stored_relative_to_a_wider_root(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    other = write_project_dataset(
        tmp_path / "deployed" / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=1, length=4
    )
    for name in [p.name for p in other.iterdir() if p.is_dir()]:  # new episode names
        (other / name).rename(other / name.replace("episode0", "episode7"))
    manifest = json.loads((other / "manifest.json").read_text())
    for record in manifest["episodes"]:
        record["dir"] = record["episode"] = record["dir"].replace("episode0", "episode7")
    (other / "manifest.json").write_text(json.dumps(manifest))
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, *cache).exit_code == 0
    grown = cli("build-memory", other, "--add-to", memory, *cache)
    assert grown.exit_code == 0, grown.output
    stored = [json.loads(line) for line in (memory / "entries.jsonl").read_text().splitlines()]
    assert all(not Path(entry["start"]).is_absolute() for entry in stored)
    loaded = FailureMemory.load(memory)  # every reference inside its (wider) root
    assert {Path(entry.start).parent.parent for entry in loaded.entries} == {data.resolve(), other.resolve()}


# Issue 50 (security): the folders a memory's images may be read from are those named where it is opened
# (the data a verb reads, the memory's folder, --data-root), never the root its own manifest records,
# and a file is judged after its links are followed.


def _private_jpeg(tmp_path: Path) -> tuple[Path, bytes]:
    """A JPEG of yours outside every folder a verb is given (a JPEG is recorded as it is, byte for byte)."""
    private = tmp_path / "home" / "u" / "Pictures" / "p.jpg"
    private.parent.mkdir(parents=True)
    data = encode_jpeg(np.random.default_rng(7).integers(0, 255, (32, 32, 3), dtype=np.uint8))
    private.write_bytes(data)
    return private, data


def _point_entries_at(memory: Path, reference: str, **manifest: object) -> None:
    """Every entry's start and end image edited to `reference`, and the manifest's fields to `manifest`."""
    entries = [json.loads(line) for line in (memory / "entries.jsonl").read_text().splitlines()]
    (memory / "entries.jsonl").write_text(
        "".join(json.dumps(entry | {"start": reference, "end": reference}) + "\n" for entry in entries)
    )
    stored = json.loads((memory / "manifest.json").read_text())
    (memory / "manifest.json").write_text(
        json.dumps({k: v for k, v in (stored | manifest).items() if v is not None})
    )


def _replayed_blobs(
    data: Path, memory: Path, out: Path, cache: list[str], *extra: str
) -> tuple[list[bytes], str]:
    result = cli("replay", data, "--memory", memory, "--out", out, "--delta", "-1", *cache, *extra)
    assert result.exit_code == 0, result.output
    recordings = sorted(out.glob("*.rrd"))
    assert recordings
    return [blob for recording in recordings for blob in blobs(recording)], result.stderr + "\n".join(
        every_text(recording) for recording in recordings
    )


@pytest.mark.parametrize("kind", ["root /", "format 1"])
def test_a_memory_naming_your_files_records_none_of_them(
    data: Path, memory: Path, cache: list[str], tmp_path: Path, kind: str
) -> None:
    """A manifest whose `data_root` is "/" with entries `home/u/Pictures/p.jpg`, or a format-1 memory with
    absolute entries: `replay` records the neighbours' images only from the data it reads, and says so."""
    private, jpeg = _private_jpeg(tmp_path)
    if kind == "root /":
        _point_entries_at(memory, str(private.relative_to(private.anchor)), data_root=private.anchor)
    else:
        _point_entries_at(memory, str(private), data_root=None, format_version=1)
    shown, said = _replayed_blobs(data, memory, tmp_path / "rec", cache)
    assert jpeg not in shown  # before: recorded as the neighbour's start and end image
    assert "lie outside the folders named for them" in said and str(private) in said
    assert "**image not read** (outside the folders named for it" in said  # in the neighbour's text
    # the user names the folder (here the memory's "/"): then, and only then, it is read
    named, _ = _replayed_blobs(data, memory, tmp_path / "named", cache, "--data-root", private.anchor)
    assert jpeg in named


def test_a_link_in_the_data_pointing_out_of_it_is_not_followed(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    """A frame of the memory's data that is a symbolic link to a file elsewhere is outside the data."""
    copy = Path(shutil.copytree(data, tmp_path / "data"))
    memory = tmp_path / "memory"
    assert cli("build-memory", copy, "--out", memory, *cache).exit_code == 0
    private, jpeg = _private_jpeg(tmp_path)
    for frame in ("front_0.png", "front_3.png"):  # the start and end image of that run's front entry
        linked = copy / "pick_cube_grasp_wp2_episode1" / frame
        linked.unlink()
        linked.symlink_to(private)
    key = "pick_cube/pick_cube_success_episode0"  # another run: its own frames are no links
    shown, said = _replayed_blobs(copy, memory, tmp_path / "rec", cache, "--trajectory", key)
    assert jpeg not in shown  # before: the lexical check let the link through
    assert "lie outside the folders named for them" in said


def test_a_detection_never_sends_a_file_the_memory_names_outside_the_data(
    data: Path, memory: Path, cache: list[str], tmp_path: Path
) -> None:
    private, jpeg = _private_jpeg(tmp_path)
    _point_entries_at(memory, str(private.relative_to(private.anchor)), data_root=private.anchor)
    episode = data / "pick_cube_grasp_wp2_episode0"
    vlm = ("--vlm-url", "--vlm-model", "m", "--json", "--score", "paper", "--delta", "-1")
    with chat_server() as server:
        result = cli("detect", episode, "--memory", memory, vlm[0], server.url, *vlm[1:], *cache)
    assert result.exit_code == 0, result.output
    found = json.loads(result.stdout)
    assert found["t_det"] == 0 and "lies outside the report's folders" in found["vlm"]["error"]
    assert server.received == []  # before: the request carried the private image
    assert str(private.parent.parent) not in found["report"]["roots"]
    assert base64.b64encode(jpeg).decode() not in result.output


@pytest.mark.parametrize("where", ["roots /", "beside the data"])
def test_explain_trusts_no_folder_a_report_names(
    data: Path, built_memory: Path, cache: list[str], tmp_path: Path, where: str
) -> None:
    """`explain det.json` reads images only from under --data-root: a report's own `roots` (edited to "/")
    are not trusted, and a folder whose name only begins like the one named (`data-private` beside
    `data`) is not inside it."""
    episode = data / "pick_cube_grasp_wp2_episode0"
    detected = cli(
        "detect", episode, "--memory", built_memory, "--json", "--score", "paper", "--delta", "-1", *cache
    )
    assert detected.exit_code == 0, detected.output
    found = json.loads(detected.stdout)
    if where == "roots /":
        private, _ = _private_jpeg(tmp_path)
        found["report"]["roots"] = ["/"]
        named: list[str] = []
    else:
        private = data.parent / "data-private" / "p.jpg"
        private.parent.mkdir(exist_ok=True)
        private.write_bytes(_private_jpeg(tmp_path)[1])
        named = ["--data-root", str(data)]
    found["report"]["neighbors"][0]["start_image"] = str(private)
    saved = tmp_path / "det.json"
    saved.write_text(json.dumps(found))
    with chat_server() as server:
        result = cli("explain", saved, "--vlm-url", server.url, "--vlm-model", "m", *named)
    assert result.exit_code == 1 and f"report image {private} lies outside" in result.stderr
    assert server.received == []
