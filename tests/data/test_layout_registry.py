"""The layout registry: one record per layout, tried in a fixed order; the first that recognises a root reads it."""

from __future__ import annotations

from pathlib import Path

import pytest
from synthetic import write_aha_dataset, write_episode, write_project_dataset

from robofailring.data.layouts import LAYOUTS, LAYOUTS_HELP, detect_layout, load_dataset
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
