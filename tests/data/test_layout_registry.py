"""The layout registry: one record per layout, tried in a fixed order; the first that recognises a root reads it."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_aha_dataset, write_episode, write_project_dataset

from robofailring.data.layouts import LAYOUTS, LAYOUTS_HELP, detect_layout, load_dataset, registry
from robofailring.data.model import Frame, Trajectory
from robofailring.errors import DataError


def test_layouts_are_tried_in_the_detection_order() -> None:
    assert [layout.name for layout in LAYOUTS] == [
        "project",
        "lerobot",
        "aloha",
        "maniskill3",
        "robomimic",
        "rosbag",
        "videos",
        "aha",
        "maniskill",
        "images",
        "episode",
    ]
    assert sorted(layout.listed for layout in LAYOUTS) == list(range(1, 12))
    for layout in LAYOUTS:  # the error lists every layout's help under its number
        assert f"({layout.listed}) {layout.help}" in LAYOUTS_HELP


def test_the_first_layout_that_recognises_a_root_reads_it(tmp_path: Path) -> None:
    project = write_project_dataset(tmp_path / "project", tasks=("pick_cube",), episodes=2, length=3)
    aha = tmp_path / "aha"
    write_aha_dataset(aha, tasks=("pick_cube",), episodes=1, length=3)
    episode = tmp_path / "pick_cube_grasp_wp2_episode0"
    write_episode(episode, "pick_cube", "grasp", length=3)
    expected = {project: "project", aha: "aha", episode: "episode"}
    for root, name in expected.items():
        first = next(layout.name for layout in LAYOUTS if layout.detect(root))  # stops at the first
        assert first == name == detect_layout(root) == load_dataset(root).layout
    # the project's episode folders are AHA-named too: the project layout comes first and wins
    aha_layout = next(layout for layout in LAYOUTS if layout.name == "aha")
    assert aha_layout.detect(project) and load_dataset(project).layout == "project"
    assert load_dataset(project).manifest is not None and load_dataset(aha).manifest is None
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DataError, match="matches no known dataset layout"):
        detect_layout(empty)
    assert not any(layout.detect(empty) for layout in LAYOUTS)


def test_a_layout_registered_by_its_module_alone_is_tried_in_its_order_read_and_listed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A new layout is one module: its `register(Layout(...))` puts it in the detection order (`detect_order`),
    in the error's list (`listed`) and in `load_dataset`; no list of layouts elsewhere names it."""
    monkeypatch.setattr(registry, "_REGISTERED", list(registry._REGISTERED))  # the registration undone after
    root = tmp_path / "notes"
    root.mkdir()
    (root / "runs.txt").write_text("run_1\n")
    image = np.full((4, 4, 3), 7, np.uint8)

    def read(root: Path, *, task: str | None) -> registry.Found:
        frames = [Frame.from_array(image)] * 3
        return [Trajectory(task=task or "notes_task", episode="run_1", views={"front": frames})], []

    registry.register(
        registry.Layout(
            name="notes",
            detect=lambda root: (root / "runs.txt").is_file(),
            read=read,
            help="a folder of notes <root>/runs.txt",
            listed=12,
            detect_order=65,  # after the ROS bags, before the video episodes
        )
    )
    order = [layout.name for layout in registry.in_detection_order()]
    assert order.index("rosbag") + 1 == order.index("notes") == order.index("videos") - 1
    assert detect_layout(root) == "notes"
    dataset = load_dataset(root)
    assert (dataset.layout, [t.key for t in dataset], dataset.episodes[0].layout) == (
        "notes",
        ["notes_task/run_1"],
        "notes",
    )
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DataError, match=r"\(12\) a folder of notes <root>/runs\.txt"):
        detect_layout(empty)
    for clash, message in (
        ({"listed": 12}, "the listed 12 of layout 'notes'"),
        ({"detect_order": 65}, "the detect_order 65"),
    ):
        again = registry.Layout(name="notes_2", detect=bool, read=read, help="", listed=13, detect_order=66)
        with pytest.raises(ValueError, match=message):  # never tried in the order its module happened to load
            registry.register(replace(again, **clash))


def test_every_module_of_the_package_is_imported_and_each_layout_registered_once() -> None:
    package = Path(registry.__file__).parent
    modules = {path.stem for path in package.glob("*.py")} - {"__init__"}
    assert {
        name.rsplit(".", 1)[-1] for name in sys.modules if name.startswith("robofailring.data.layouts.")
    } >= modules
    names = [layout.name for layout in registry.in_detection_order()]
    assert names == [layout.name for layout in LAYOUTS] and len(set(names)) == len(names)
    orders = [layout.detect_order for layout in LAYOUTS]
    assert orders == sorted(orders) and len(set(orders)) == len(orders)
