"""The embedded PyBullet FailGen: layout, honest labels, determinism, visible outcomes (real physics)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robofailring.data import Outcome, load_dataset
from robofailring.data.grounding import failure_type, ground
from robofailring.data.images import read_image
from robofailring.errors import DataError
from robofailring.sim import (
    FAILURE_FAMILIES,
    FAILURE_MODES,
    KINDS,
    TASKS,
    VIEWS,
    GenerateConfig,
    contact_sheet,
    generate_dataset,
    run_episode,
)

pytestmark = pytest.mark.slow  # simulation or end-to-end: the full lane only (scripts/test.sh)

TASK = "pick_cube"
MODES = KINDS  # the seven failure families and success
FRAMES = 12
SIZE = 64


def _red_fraction(image: np.ndarray) -> float:
    """Share of pixels of the target cube's red (in-distribution colour)."""
    rgb = image.astype(int)
    red = (rgb[..., 0] > 140) & (rgb[..., 1] < 90) & (rgb[..., 2] < 90)
    return float(red.mean())


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sim") / "demo"
    ticks: list[int] = []
    config = GenerateConfig(
        out=out, tasks=(TASK,), modes=MODES, episodes=1, image_size=SIZE, frames=FRAMES, workers=2, seed=7
    )
    assert generate_dataset(config, progress=ticks.append) == out
    assert ticks == [1] * len(MODES)
    return out


def _manifest(root: Path) -> dict:
    return json.loads((root / "manifest.json").read_text())


def test_layout_and_manifest(dataset: Path) -> None:
    manifest = _manifest(dataset)
    assert manifest["format"] == "robofailring-dataset"
    assert manifest["format_version"] == 1
    assert manifest["generator"] == "robofailring.sim"
    assert manifest["views"] == list(VIEWS) == ["front", "overhead", "wrist"]
    assert manifest["tasks"] == [TASK]
    assert manifest["image_size"] == SIZE and manifest["ood"] is False and manifest["seed"] == 7
    assert manifest["config"]["frames"] == FRAMES and manifest["config"]["modes"] == list(MODES)
    records = manifest["episodes"]
    assert len(records) == len(MODES)
    assert len({r["episode"] for r in records}) == len(records)
    assert not [p for p in dataset.iterdir() if p.name.startswith(".")]
    for record in records:
        folder = dataset / record["dir"]
        expected = {f"{view}_{i}.png" for view in VIEWS for i in range(FRAMES)} | {"signals.npz"}
        assert {p.name for p in folder.iterdir()} == expected
        assert record["signals"]["file"] == "signals.npz"
        assert read_image(folder / "wrist_0.png").shape == (SIZE, SIZE, 3)
        number = int(record["dir"].rsplit("episode", 1)[1])
        assert record["split"] == ("train" if number % 2 == 0 else "test")
        if record["label"] is None:
            assert record["dir"] == f"{TASK}_success_episode{number}"
            assert record["onset_frame"] is None
        else:
            assert isinstance(record["onset_frame"], int) and 0 <= record["onset_frame"] < FRAMES
            assert record["dir"] == f"{TASK}_{record['label']}_episode{number}"
            ground(record["label"])  # a FailGen symbol the grounding accepts

    trajectories = list(load_dataset(dataset).trajectories())
    assert len(trajectories) == len(records)
    by_episode = {r["episode"]: r for r in records}
    for trajectory in trajectories:
        record = by_episode[trajectory.episode]
        assert trajectory.task == TASK
        assert trajectory.symbol == record["label"]
        assert trajectory.outcome == Outcome(record["outcome"])
        assert trajectory.split == record["split"]
        assert trajectory.onset_frame == record["onset_frame"]
        assert {view: len(frames) for view, frames in trajectory.views.items()} == dict.fromkeys(
            VIEWS, FRAMES
        )


def test_labels_are_honest(dataset: Path) -> None:
    records = _manifest(dataset)["episodes"]
    for record in records:
        goal = record["goal_check"]
        wrist_end = read_image(dataset / record["dir"] / f"wrist_{FRAMES - 1}.png")
        if record["outcome"] == "failure":
            assert goal["passed"] is False and record["label"] is not None
            assert failure_type(record["label"]) == record["kind"]
            assert goal["lift_m"] < 0.1  # the cube is not up in the air
            assert _red_fraction(wrist_end) < 0.05  # and not in front of the wrist camera
        else:
            assert goal["passed"] is True and record["label"] is None
            assert goal["lift_m"] > 0.1
            assert _red_fraction(wrist_end) > 0.08  # the held cube fills the wrist view
    kinds = {r["kind"]: r for r in records}
    assert kinds["success"]["perturbation"] is None and kinds["success"]["outcome"] == "success"
    # The injected failures of this fixture are strong enough to fail.
    for kind in FAILURE_FAMILIES:
        assert kinds[kind]["outcome"] == "failure", kinds[kind]
        assert kinds[kind]["perturbation"] in FAILURE_MODES
    assert kinds["wrong_object"]["label"] == "wrong_object"


def test_failure_and_success_end_frames_differ(dataset: Path) -> None:
    records = {r["kind"]: r for r in _manifest(dataset)["episodes"]}
    success = records["success"]["dir"]
    for kind in FAILURE_FAMILIES:
        failure = records[kind]["dir"]
        diffs = []
        for view in VIEWS:
            a = read_image(dataset / success / f"{view}_{FRAMES - 1}.png").astype(float)
            b = read_image(dataset / failure / f"{view}_{FRAMES - 1}.png").astype(float)
            diffs.append(float(np.abs(a - b).mean()))
        assert max(diffs) > 4.0, (kind, diffs)
        # The first frames show the same start scene (only the hand's later path differs).
        first = read_image(dataset / success / "front_0.png").astype(float)
        other = read_image(dataset / failure / "front_0.png").astype(float)
        assert float(np.abs(first - other).mean()) < max(diffs)


def test_same_seed_same_images(dataset: Path) -> None:
    record = next(r for r in _manifest(dataset)["episodes"] if r["kind"] == "grasp")
    with run_episode(TASK, "grasp", record["seed"], image_size=SIZE, frames=FRAMES) as run:
        frames = list(run)
        result = run.run_to_end()
    assert result.label == record["label"] and result.outcome == record["outcome"]
    for i in (0, FRAMES // 2, FRAMES - 1):
        for view in VIEWS:
            written = read_image(dataset / record["dir"] / f"{view}_{i}.png")
            assert np.array_equal(frames[i][view], written), (i, view)
    with run_episode(TASK, "grasp", record["seed"] + 1, image_size=SIZE, frames=2) as other:
        start = next(iter(other))
    assert not np.array_equal(start["overhead"], frames[0]["overhead"])  # the cubes are jittered


def test_stepping_can_stop_early() -> None:
    with run_episode("push_cube", "success", 3, image_size=32, frames=10) as run:
        assert run.frames == 10
        for index, images in enumerate(run):
            assert set(images) == set(VIEWS)
            assert images["wrist"].shape == (32, 32, 3) and images["wrist"].dtype == np.uint8
            if index == 2:
                run.stop()
        assert run.result is not None
        assert run.result.frames == 3 and run.result.stopped_early
        assert run.result.outcome == "failure"  # stopped before the push


def test_ood_changes_the_look() -> None:
    with run_episode("stack_cube", "success", 5, image_size=48, frames=2) as plain:
        a = next(iter(plain))
    with run_episode("stack_cube", "success", 5, image_size=48, frames=2, ood=True) as shifted:
        b = next(iter(shifted))
    for view in ("front", "overhead"):
        assert float(np.abs(a[view].astype(float) - b[view].astype(float)).mean()) > 10.0


def test_cache_replace_and_refuse(tmp_path: Path, dataset: Path) -> None:
    same = GenerateConfig(
        out=dataset, tasks=(TASK,), modes=MODES, episodes=1, image_size=SIZE, frames=FRAMES, workers=1, seed=7
    )
    before = (dataset / "manifest.json").stat().st_mtime_ns
    ticks: list[int] = []
    assert generate_dataset(same, progress=ticks.append) == dataset
    assert ticks == [] and (dataset / "manifest.json").stat().st_mtime_ns == before

    out = tmp_path / "small"
    tiny = GenerateConfig(
        out=out, tasks=("put_in_tray",), modes=("success",), episodes=1, image_size=32, frames=2
    )
    generate_dataset(tiny)
    ood = GenerateConfig(
        out=out, tasks=("put_in_tray",), modes=("success",), episodes=1, image_size=32, frames=2, ood=True
    )
    generate_dataset(ood)
    manifest = _manifest(out)
    assert manifest["ood"] is True and [r["split"] for r in manifest["episodes"]] == ["ood"]
    assert [p.name for p in tmp_path.iterdir()] == ["small"]  # no temporary folders left behind

    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "keep.txt").write_text("mine")
    with pytest.raises(DataError, match="refusing"):
        generate_dataset(GenerateConfig(out=foreign, tasks=("pick_cube",), modes=("success",), episodes=1))
    assert (foreign / "keep.txt").read_text() == "mine"


def test_config_rejects_unknown_names(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="unknown task"):
        GenerateConfig(out=tmp_path, tasks=("fly",))
    with pytest.raises(ValueError, match="unknown mode"):
        GenerateConfig(out=tmp_path, modes=("explode",))
    assert set(TASKS) == {"pick_cube", "push_cube", "stack_cube", "put_in_tray"}


def test_contact_sheet(tmp_path: Path, dataset: Path) -> None:
    out = contact_sheet(dataset, tmp_path / "sheet.png", tile=48)
    image = read_image(out)
    assert image.shape[1] > 3 * 48 and image.shape[0] > 8 * 48


def test_the_robot_records_its_signals_beside_the_cameras(dataset: Path) -> None:
    """Joint positions, gripper width, end-effector pose and the commanded action at every frame, as the
    manifest names them; a grasp that never forms shows in the gripper: it never closes on a cube."""
    by_label = {t.label: t for t in load_dataset(dataset).trajectories()}
    success, grasp = (
        by_label["success"],
        next(t for label, t in by_label.items() if label.startswith("grasp")),
    )
    signals, skipped = success.read_signals()
    assert skipped == [] and sorted(signals) == ["action", "ee_pose", "gripper_width", "joint_positions"]
    assert signals["joint_positions"].dims[:2] == ("panda_joint1", "panda_joint2")
    assert signals["ee_pose"].dims == ("x", "y", "z", "qx", "qy", "qz", "qw")
    assert signals["action"].kind.value == "action" and signals["action"].values.shape == (FRAMES, 8)
    width = signals["gripper_width"].values[:, 0]
    assert width[0] == pytest.approx(0.08, abs=2e-3)  # open at the start
    assert 0.02 < width.min() < 0.06  # closed on the cube (its size) while carrying it
    quaternion = signals["ee_pose"].values[:, 3:]
    np.testing.assert_allclose(np.linalg.norm(quaternion, axis=1), 1.0, atol=1e-3)
    missed, _ = grasp.read_signals(["gripper_width"])
    assert missed["gripper_width"].values.min() > 0.07 or missed["gripper_width"].values.min() < 0.01
