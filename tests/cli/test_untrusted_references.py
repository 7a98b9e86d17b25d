"""References read from a shared memory or dataset stay inside their own root (issue 45, item 1): an
edited `entries.jsonl` or `manifest.json` cannot make a verb read, record or send another file of yours."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from fault_helpers import cli, refused
from synthetic import write_project_dataset

from robofailring import FailureMemory, load_dataset


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
