"""Folders of image episodes with the user's own names, tasks from a labels file's task column."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from pipeline import run_pipeline
from synthetic import synthetic_frame

from robofailring import load_dataset, load_trajectory
from robofailring.data.images import write_png
from robofailring.data.model import Trajectory
from robofailring.data.splits import split_of
from robofailring.errors import DataError

LENGTH = 10
VIEWS = ("front", "wrist")


def names(count: int) -> list[str]:
    return [f"2026-11-30_14-{minute:02d}" for minute in range(count)]


def write_runs(root: Path, symbols: dict[str, str | None], tasks: dict[str, str], *, nested: bool) -> Path:
    for episode, symbol in symbols.items():
        for v, view in enumerate(VIEWS):
            for t in range(LENGTH):
                image = synthetic_frame(tasks[episode], symbol, v, t, LENGTH, size=32)
                if nested:
                    (root / episode / view).mkdir(parents=True, exist_ok=True)
                    write_png(root / episode / view / f"{t:06d}.png", image)
                else:
                    (root / episode).mkdir(parents=True, exist_ok=True)
                    write_png(root / episode / f"{view}_{t}.png", image)
    return root


def plan(count: int) -> tuple[dict[str, str | None], dict[str, str]]:
    """Two tasks; per task and side of the hash split, one failure and one success at least."""
    tasks = {name: ("pick_cube", "push_cube")[i % 2] for i, name in enumerate(names(count))}
    symbols: dict[str, str | None] = {}
    seen: dict[tuple[str, str], int] = {}
    for name, task in tasks.items():
        side = split_of(Trajectory(task=task, episode=name, views={}), has_splits=False, test_fraction=0.5)
        number = seen[(task, side)] = seen.get((task, side), 0) + 1
        symbols[name] = "grasp_wp2" if number == 1 else None
    return symbols, tasks


def write_labels(path: Path, symbols: dict[str, str | None], tasks: dict[str, str]) -> Path:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "outcome", "symbol", "task"])
        for name, symbol in symbols.items():
            writer.writerow([name, "failure" if symbol else "success", symbol or "", tasks[name]])
    return path


@pytest.mark.slow  # an end-to-end run of every verb: the full lane
@pytest.mark.parametrize("nested", [False, True])
def test_image_episodes_with_any_names_through_every_verb(tmp_path: Path, nested: bool) -> None:
    symbols, tasks = plan(16)
    root = write_runs(tmp_path / "runs", symbols, tasks, nested=nested)
    labels = write_labels(tmp_path / "labels.csv", symbols, tasks)
    dataset = load_dataset(root, labels=labels)
    assert dataset.layout == "images" and dataset.views == list(VIEWS) and dataset.skipped == []
    first = dataset.episodes[3]
    assert first.episode == names(16)[3] and first.task == tasks[first.episode]
    written = synthetic_frame(first.task, symbols[first.episode], 1, 4, LENGTH, size=32)
    assert np.array_equal(first.views["wrist"][4].load(), written)
    failure = next(name for name, symbol in symbols.items() if symbol)
    found = run_pipeline(tmp_path, root, trajectory=failure, options=["--labels", labels])
    assert found["info"]["layout"] == "images" and found["info"]["views_read"] == list(VIEWS)
    assert sorted(found["info"]["tasks"]) == ["pick_cube", "push_cube"]
    assert found["detect"]["layout"] == "images" and found["detect"]["task"] == tasks[failure]
    assert len(found["recordings"]) == 1 and found["evaluation"]["trajectories"]


def test_without_a_task_the_error_says_how_to_give_one(tmp_path: Path) -> None:
    symbols, tasks = plan(2)
    root = write_runs(tmp_path / "runs", symbols, tasks, nested=False)
    with pytest.raises(DataError, match="cannot tell the task of 2 episode"):
        load_dataset(root)
    assert {t.task for t in load_dataset(root, task="pick_cube")} == {"pick_cube"}


def test_view_named_files_one_level_down_are_episodes_not_views(tmp_path: Path) -> None:
    """Before this layout, `run_a/front_0.png` made `run_a` a view and the error named two frames 0 in it."""
    root = tmp_path / "runs"
    for episode in ("run_a", "run_b"):
        for v, view in enumerate(VIEWS):
            (root / episode).mkdir(parents=True, exist_ok=True)
            write_png(root / episode / f"{view}_0.png", np.full((8, 8, 3), v, np.uint8))
            write_png(root / episode / f"{view}_1.png", np.full((8, 8, 3), v, np.uint8))
    dataset = load_dataset(root, task="pick_cube")
    assert dataset.layout == "images" and [t.episode for t in dataset] == ["run_a", "run_b"]
    assert dataset.views == list(VIEWS)


def test_trajectory_is_chosen_before_views_are_checked(tmp_path: Path) -> None:
    """`--trajectory run_a --views wrist` reads run_a's wrist; run_b has no wrist camera and is not asked for."""
    root = tmp_path / "runs"
    for episode, views in (("run_a", VIEWS), ("run_b", VIEWS[:1])):
        for v, view in enumerate(views):
            (root / episode / view).mkdir(parents=True)
            for t in range(3):
                write_png(root / episode / view / f"{t}.png", np.full((8, 8, 3), 10 * v + t, np.uint8))
    chosen = load_trajectory(root, key="run_a", task="pick_cube", views="wrist=hand")
    assert chosen.episode == "run_a" and chosen.view_names == ["hand"]
    assert int(chosen.views["hand"][2].load()[0, 0, 0]) == 12
    with pytest.raises(DataError, match="no view 'wrist' in trajectory pick_cube/run_b"):
        load_dataset(root, task="pick_cube", views="wrist")  # every trajectory is used: each needs it


def write_frames(folder: Path, names: list[str], value: int = 0) -> None:
    """PNG frames whose first pixel holds their place in `names` (and `value` in the blue channel)."""
    folder.mkdir(parents=True, exist_ok=True)
    for place, name in enumerate(names):
        write_png(folder / name, np.full((8, 8, 3), (place, 50, value), np.uint8))


def test_episode_folders_of_one_camera_are_episodes_named_by_the_files(tmp_path: Path) -> None:
    root = tmp_path / "runs"
    for run in range(3):
        write_frames(root / f"run_{run}", [f"front_{t}.png" for t in range(4 + run)], value=run)
    dataset = load_dataset(root, task="pick_cube", views="front=scene")
    assert dataset.layout == "images" and dataset.skipped == []
    assert [(t.episode, t.view_names, t.length) for t in dataset] == [
        ("run_0", ["scene"], 4), ("run_1", ["scene"], 5), ("run_2", ["scene"], 6),
    ]  # fmt: skip
    assert dataset.episodes[2].views["scene"][5].load()[0, 0].tolist() == [5, 50, 2]
    alone = load_trajectory(root / "run_1", task="pick_cube")  # one of them, given alone
    assert alone.view_names == ["front"] and alone.length == 5
    write_frames(root / "run_3", [f"{t:06d}.png" for t in range(3)], value=3)  # a number alone: view `image`
    bare = load_trajectory(root / "run_3", task="pick_cube")
    assert bare.view_names == ["image"] and bare.views["image"][2].load()[0, 0].tolist() == [2, 50, 3]


@pytest.mark.parametrize(
    "names",
    [
        {"front": "frame_{t}.png", "wrist": "frame_{t}.png"},  # a frame word names no camera
        {"front": "front_{t}.png", "wrist": "wrist_{t}.png"},  # the folder's own name
    ],
)
def test_view_folders_of_one_episode_stay_one_episode(tmp_path: Path, names: dict[str, str]) -> None:
    episode = tmp_path / "2026-11-30_14-02"
    for v, (view, pattern) in enumerate(names.items()):
        write_frames(episode / view, [pattern.format(t=t) for t in range(3)], value=v)
    for trajectory in (load_trajectory(episode, task="t"), *load_dataset(episode, task="t")):
        assert trajectory.episode == "2026-11-30_14-02" and trajectory.view_names == ["front", "wrist"]
        assert trajectory.views["wrist"][1].load()[0, 0].tolist() == [1, 50, 1]


def test_folders_of_images_numbered_alone_are_one_episode_and_a_dataset_verb_says_so(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """`runs/run_0/000.png` looks like `ep/front/000.png`: read as docs/data.md says, one episode, with a warning."""
    root = tmp_path / "runs"
    for run in range(3):
        write_frames(root / f"run_{run}", [f"{t:06d}.png" for t in range(3)], value=run)
    with caplog.at_level("WARNING", logger="robofailring"):
        assert load_trajectory(root, task="t").view_names == ["run_0", "run_1", "run_2"]
        assert not caplog.records  # one episode is what detect asked for
        dataset = load_dataset(root, task="t")
    assert dataset.layout == "episode" and [t.view_names for t in dataset] == [["run_0", "run_1", "run_2"]]
    (record,) = caplog.records
    assert f"{root} is read as one episode whose views are its folders run_0, run_1, run_2" in record.message
    assert "name its images <camera>_<n>.png" in record.message
    write_frames(tmp_path / "one" / "run_0", ["front_0.png", "front_1.png"])  # one folder: a view folder
    (single,) = load_dataset(tmp_path / "one", task="t")
    assert single.episode == "one" and single.view_names == ["run_0"]


def test_view_folders_named_in_their_files_are_read_without_a_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    episode = tmp_path / "ep"
    for view in VIEWS:
        write_frames(episode / view, [f"{view}_{t}.png" for t in range(3)])
    with caplog.at_level("WARNING", logger="robofailring"):
        assert [t.view_names for t in load_dataset(episode, task="t")] == [list(VIEWS)]
    assert not caplog.records
