"""What a real bag's other contents do to a verb's status (issue 35, item 9): a bag's non-image topics are
not skipped data, a bag of no camera in a folder does not fail `--trajectory` of another, and a topic of
one message is a skipped short view, as in every layout."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli
from rosbag_writer import write_bag
from synthetic import synthetic_frame

from robofailring import load_dataset, load_trajectory
from robofailring.errors import DataError

FRONT = ("/cam_front/image_raw", "rgb8")
DEPTH = ("/camera/depth/image_rect_raw", "16UC1")
ROBOT_TOPICS = ["/joint_states", "/tf"]  # what every real bag holds beside its cameras


def frame(number: int, t: int) -> np.ndarray:
    return synthetic_frame("pick_cube", "grasp_wp2", number, t, 6, size=32)


@pytest.fixture(scope="module")
def memory(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A memory of one failure bag (its camera /cam_front/image_raw), task pick_cube."""
    root = tmp_path_factory.mktemp("bag-memory")
    write_bag(root / "bags" / "run_0", kind="mcap", topics=(FRONT,), frames=frame, count=6)
    labels = root / "labels.csv"
    labels.write_text("episode,outcome,symbol\nrun_0,failure,grasp_wp2\n")
    out = root / "memory"
    built = cli("build-memory", root / "bags", "--labels", labels, "--task", "pick_cube", "--out", out,
                "--cache-dir", root / "cache")  # fmt: skip
    assert built.exit_code == 0, built.output
    return out


def detect(bags: Path, memory: Path, *args: object) -> tuple[int, str]:
    result = cli("detect", bags, "--memory", memory, "--task", "pick_cube", "--cache-dir",
                 memory.parent / "cache", *args)  # fmt: skip
    return result.exit_code, result.output


def test_a_bags_other_topics_are_not_skipped_data(memory: Path, tmp_path: Path) -> None:
    bags = tmp_path / "bags"
    write_bag(bags / "run_1", kind="mcap", topics=(FRONT,), frames=frame, count=6, extra_topics=ROBOT_TOPICS)
    write_bag(
        bags / "run_2.bag", kind="ros1", topics=(FRONT,), frames=frame, count=6, extra_topics=ROBOT_TOPICS
    )
    assert load_dataset(bags, task="pick_cube").skipped == []
    status, output = detect(bags, memory, "--trajectory", "run_1")
    assert status == 0 and "not read" not in output and "/joint_states" not in output, output  # was 3


def test_a_bag_of_no_camera_is_listed_only_where_it_is_asked_for(memory: Path, tmp_path: Path) -> None:
    bags = tmp_path / "bags"
    write_bag(bags / "run_1", kind="mcap", topics=(FRONT,), frames=frame, count=6)
    depth = write_bag(bags / "run_2", kind="mcap", topics=(DEPTH,), frames=frame, count=6)
    status, output = detect(bags, memory, "--trajectory", "run_1")
    assert status == 0 and "run_2" not in output, (
        output
    )  # was 2: "ROS bag …/run_2 has no readable image topic"
    dataset = load_dataset(bags, task="pick_cube")
    assert [t.episode for t in dataset] == ["run_1"]
    (skipped,) = dataset.skipped
    assert skipped.path == depth and "has no readable image topic" in skipped.reason
    assert "/camera/depth/image_rect_raw (encoding '16UC1' (a depth image" in skipped.reason
    with pytest.raises(DataError, match="no trajectory 'run_2'") as asked:  # asked for by name: why it is not
        load_trajectory(bags, key="run_2", task="pick_cube")
    assert "has no readable image topic" in str(asked.value)
    result = cli("build-memory", bags, "--out", tmp_path / "out", "--cache-dir", tmp_path / "cache",
                 "--labels", write_labels(tmp_path, "run_1"), "--task", "pick_cube")  # fmt: skip
    assert result.exit_code == 3 and f"  {depth}: not read: ROS bag" in result.output, result.output


def write_labels(folder: Path, *failures: str) -> Path:
    labels = folder / "labels.csv"
    labels.write_text(
        "episode,outcome,symbol\n" + "".join(f"{name},failure,grasp_wp2\n" for name in failures)
    )
    return labels


def test_a_topic_of_one_message_is_a_skipped_short_view(memory: Path, tmp_path: Path) -> None:
    bags = tmp_path / "bags"
    snapshot = "/cam_snapshot/image_raw"  # one image taken at the start
    write_bag(bags / "run_1", kind="mcap", topics=(FRONT, (snapshot, "rgb8")), frames=frame, count=6,
              timing={snapshot: (0, 10**10)})  # fmt: skip
    trajectory = load_trajectory(bags, key="run_1", task="pick_cube")
    assert {view: len(frames) for view, frames in trajectory.views.items()} == {FRONT[0]: 6, snapshot: 1}
    assert np.array_equal(trajectory.views[FRONT[0]][5].load(), frame(0, 5))  # the 6 frames, not one
    status, output = detect(bags, memory, "--trajectory", "run_1", "--json")
    assert status == 3 and "error:" not in output, output  # was 2: every view cut to the one frame
    assert f"view {snapshot}: 1 frame(s), fewer than 2: not scored" in output
