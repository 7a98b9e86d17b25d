"""ROS bags written by rosbags' own writers (ROS 1, ROS 2 MCAP and SQLite) read back and run through every verb."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rosbag_writer import START_NS, stored, write_bag
from rrd import properties, rows
from synthetic import synthetic_frame
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring import load_dataset, load_trajectory
from robofailring.data.frame_ref import read_frame
from robofailring.data.layouts.rosbag import BagFile
from robofailring.errors import DataError
from robofailring.memory.references import check_references, reference_file

ENCODINGS = (
    ("/cam_front/image_raw", "rgb8"),
    ("/cam_left/image_raw", "bgr8"),
    ("/cam_wrist/image_mono", "mono8"),
    ("/cam_top/image_raw/compressed", "jpeg"),
    ("/camera/color/image_rgba", "rgba8"),
    ("/zed/left/image_rect_color", "bgra8"),  # the ZED wrapper's encoding
    ("/cv_bridge/image", "8UC3"),  # OpenCV's BGR under its type name
)
KINDS = ("ros1", "mcap", "sqlite3")


def frame(number: int, t: int) -> np.ndarray:
    return synthetic_frame("pick_cube", None, number, t, 10, size=32)


def bag_path(root: Path, name: str, kind: str) -> Path:
    return root / (f"{name}.bag" if kind == "ros1" else name)


@pytest.mark.parametrize("kind", KINDS)
def test_every_encoding_reads_back_what_was_written(kind: str, tmp_path: Path) -> None:
    path = write_bag(
        bag_path(tmp_path / "bags", "run_1", kind),
        kind=kind,
        topics=ENCODINGS,
        frames=frame,
        count=10,
        extra_topics=["/chatter"],
    )
    dataset = load_dataset(tmp_path / "bags", task="pick_cube")
    assert dataset.layout == "rosbag"
    (trajectory,) = dataset
    assert trajectory.episode == "run_1" and trajectory.task == "pick_cube" and trajectory.length == 10
    assert trajectory.view_names == sorted(topic for topic, _ in ENCODINGS)
    assert trajectory.fps == pytest.approx(10.0)
    assert dataset.skipped == []  # /chatter is no camera: not data left unread (issue 35, item 9)
    for number, (topic, encoding) in enumerate(ENCODINGS):
        frames = trajectory.views[topic]
        for t in (9, 0, 4):  # out of order: each frame reads its own message
            image = frames[t].load()
            expected = stored(frame(number, t), encoding)
            assert image.shape == (32, 32, 3) and image.dtype == np.uint8
            if encoding == "jpeg":
                assert np.abs(image.astype(int) - expected.astype(int)).mean() < 6
            else:
                assert np.array_equal(image, expected), (topic, t)
    reference = trajectory.views["/cam_left/image_raw"][4].reference
    assert reference == f"{path}#topic=/cam_left/image_raw&message=4"
    assert reference_file(reference) == str(path) and check_references([reference]).ok
    assert np.array_equal(read_frame(reference), frame(1, 4))


def test_a_ros2_bag_folder_is_one_trajectory_and_its_frames_are_keyed_by_content(tmp_path: Path) -> None:
    topics = ENCODINGS[:1]
    mcap = write_bag(tmp_path / "a" / "run_1", kind="mcap", topics=topics, frames=frame, count=4)
    sqlite = write_bag(tmp_path / "b" / "run_1", kind="sqlite3", topics=topics, frames=frame, count=4)
    one, other = load_trajectory(mcap), load_trajectory(sqlite)
    assert one.episode == "run_1" and one.task == "a" and one.length == 4
    keys = [f.content_key() for f in one.views["/cam_front/image_raw"]]
    assert keys == [f.content_key() for f in other.views["/cam_front/image_raw"]]  # same messages, same keys
    assert len(set(keys)) == 4


def test_two_messages_at_one_time_are_both_read(tmp_path: Path) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    Image = store.types["sensor_msgs/msg/Image"]
    with Writer(tmp_path / "same", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection("/cam", "sensor_msgs/msg/Image", typestore=store)
        for value in (10, 20, 30):
            message = Image(
                header=store.types["std_msgs/msg/Header"](
                    stamp=store.types["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id=""
                ),
                height=2, width=2, encoding="mono8", is_bigendian=0, step=2,
                data=np.full(4, value, dtype=np.uint8),
            )  # fmt: skip
            writer.write(
                connection, 5 if value < 30 else 6, store.serialize_cdr(message, "sensor_msgs/msg/Image")
            )
    frames = load_trajectory(tmp_path / "same", task="t").views["/cam"]
    assert [int(f.load()[0, 0, 0]) for f in frames] == [10, 20, 30]


def write_runs(root: Path) -> Path:
    """Eight bags of three storage kinds: three failures, five successes; a labels file names them."""
    runs = [
        ("run_01", "grasp_wp2"), ("run_02", None), ("run_03", "rotation_x_wp1"), ("run_04", None),
        ("run_05", "grasp_wp2"), ("run_06", None), ("run_07", None), ("run_08", None),
    ]  # fmt: skip
    for number, (name, symbol) in enumerate(runs):
        kind = KINDS[number % 3]
        write_bag(
            bag_path(root / "bags", name, kind),
            kind=kind,
            topics=(("/cam_front/image_raw", "rgb8"), ("/cam_wrist/image_raw/compressed", "jpeg")),
            frames=lambda view, t, symbol=symbol: synthetic_frame("pick_cube", symbol, view, t, 10, size=32),
            count=10,
        )
    labels = root / "labels.csv"
    labels.write_text(
        "episode,outcome,symbol\n"
        + "".join(f"{name},{'failure' if symbol else 'success'},{symbol or ''}\n" for name, symbol in runs)
    )
    return labels


@pytest.mark.slow  # an end-to-end run of every verb: the full lane
def test_a_folder_of_bags_goes_through_every_verb(tmp_path: Path) -> None:
    labels = write_runs(tmp_path)
    bags = tmp_path / "bags"
    runner = CliRunner()
    cache = ["--cache-dir", str(tmp_path / "cache")]
    data = [str(bags), "--labels", str(labels)]
    memory = tmp_path / "memory"
    built = runner.invoke(app, ["build-memory", *data, "--out", str(memory), *cache])
    assert built.exit_code == 0, built.output
    assert "from 6 failure views" in built.output and "3 failure trajectories over 1 tasks" in built.output
    entries = [json.loads(line) for line in (memory / "entries.jsonl").read_text().splitlines()]
    assert sorted({(e["episode"], e["symbol"]) for e in entries}) == [
        ("run_01", "grasp_wp2"), ("run_03", "rotation_x_wp1"), ("run_05", "grasp_wp2"),
    ]  # fmt: skip
    assert {e["view"] for e in entries} == {"/cam_front/image_raw", "/cam_wrist/image_raw/compressed"}
    # dense: each entry's image is the message of the frame it pairs, the last (message 9) kept in every view
    assert all("#topic=/cam_" in e["end"] and e["end"].endswith(f"&message={e['frame']}") for e in entries)
    assert sum(e["frame"] == 9 for e in entries) == 6 and min(e["frame"] for e in entries) == 1

    calibrated = runner.invoke(
        app, ["calibrate", *data, "--memory", str(memory), "--target-fpr", "0.2", *cache]
    )
    assert calibrated.exit_code == 0, calibrated.output
    calibration = json.loads((memory / "manifest.json").read_text())["calibration"]
    assert calibration["successes"] == 5 and calibration["target_fpr"] == 0.2

    detected = runner.invoke(
        app, ["detect", str(bags), "--memory", str(memory), "--trajectory", "run_03", "--json", *cache]
    )
    assert detected.exit_code == 0, detected.output
    report = json.loads(detected.stdout)
    assert report["length"] == 10 and set(report["views"]) == {e["view"] for e in entries}

    out = tmp_path / "recordings"
    replayed = runner.invoke(
        app, ["replay", *data, "--memory", str(memory), "--trajectory", "run_02", "--out", str(out), *cache]
    )
    assert replayed.exit_code == 0, replayed.output
    (recording,) = out.glob("*.rrd")
    assert properties(recording)["task"] == "bags"
    camera = rows(recording, "/camera/cam_front/image_raw", "EncodedImage:blob")  # Rerun folds the "//"
    assert [t for t, _ in camera] == list(range(10))
    assert rows(recording, "/neighbors/cam_front/image_raw/0/end", "EncodedImage:blob")  # read from its bag

    evaluation = tmp_path / "eval"
    evaluated = runner.invoke(
        app, ["evaluate", *data, "--out", str(evaluation), "--target-fpr", "0.3", *cache]
    )
    assert evaluated.exit_code == 0, evaluated.output
    result = json.loads((evaluation / "evaluation.json").read_text())
    assert (
        result["calibrated"] and result["failures"] + result["successes"] == len(result["trajectories"]) == 3
    )
    assert result["skipped_inputs"] == []


def test_a_bag_without_an_image_topic_is_a_named_error(tmp_path: Path) -> None:
    write_bag(
        tmp_path / "bags" / "run_1",
        kind="mcap",
        topics=(),
        frames=frame,
        count=0,
        extra_topics=["/chatter", "/tf"],
    )
    result = CliRunner().invoke(
        app,
        [
            "build-memory",
            str(tmp_path / "bags"),
            "--out",
            str(tmp_path / "memory"),
            "--cache-dir",
            str(tmp_path / "c"),
        ],
    )
    assert result.exit_code == 2, result.output
    assert "has no readable image topic" in result.output
    assert "/chatter (std_msgs/msg/String), /tf (std_msgs/msg/String)" in result.output
    assert not (tmp_path / "memory").exists()


DEPTH = (
    ("/camera/depth/image_rect_raw", "16UC1"),  # RealSense
    ("/camera/depth/image_rect_raw/compressedDepth", "compressedDepth"),
    ("/camera/ir/image", "mono16"),
)


@pytest.mark.parametrize("kind", KINDS)
def test_depth_topics_are_listed_as_not_read_and_the_colour_topic_is_read(kind: str, tmp_path: Path) -> None:
    write_bag(
        bag_path(tmp_path / "bags", "run_1", kind),
        kind=kind,
        topics=(("/camera/color/image_raw", "rgb8"), *DEPTH),
        frames=frame,
        count=3,
    )
    (trajectory,) = load_dataset(tmp_path / "bags", task="pick_cube")
    assert trajectory.view_names == ["/camera/color/image_raw"] and trajectory.length == 3
    assert np.array_equal(trajectory.views["/camera/color/image_raw"][2].load(), frame(0, 2))
    reasons = {s.view: s.reason for s in trajectory.skipped}
    assert set(reasons) == {topic for topic, _ in DEPTH}
    assert reasons["/camera/depth/image_rect_raw"].startswith(
        "topic /camera/depth/image_rect_raw has encoding '16UC1' (a depth image, not a colour camera): not read"
    )
    assert "format '16UC1; compressedDepth png' (a depth image" in reasons[DEPTH[1][0]]
    assert "encoding 'mono16' (a depth image" in reasons["/camera/ir/image"]
    with pytest.raises(DataError) as error:  # asked for by name: why it is not there
        load_trajectory(tmp_path / "bags", key="run_1", task="t", views="/camera/depth/image_rect_raw=depth")
    assert "view '/camera/depth/image_rect_raw' of trajectory t/run_1" in str(error.value)
    assert "has encoding '16UC1' (a depth image, not a colour camera)" in str(error.value)


def test_a_bag_of_depth_topics_only_is_a_named_error(tmp_path: Path) -> None:
    write_bag(tmp_path / "bags" / "run_1", kind="mcap", topics=DEPTH[:1], frames=frame, count=3)
    result = CliRunner().invoke(
        app,
        [
            "build-memory",
            str(tmp_path / "bags"),
            "--out",
            str(tmp_path / "memory"),
            "--cache-dir",
            str(tmp_path / "c"),
        ],
    )
    assert result.exit_code == 2, result.output
    assert "has no readable image topic" in result.output and "rgb8, bgr8, 8UC3" in result.output
    assert "it holds: /camera/depth/image_rect_raw (encoding '16UC1' (a depth image" in result.output
    assert not (tmp_path / "memory").exists()


def test_views_at_different_rates_follow_the_slowest_topics_messages(tmp_path: Path) -> None:
    """30 Hz, 10 Hz, and 20 Hz from 0.15 s: frame i is each topic's latest message at or before 0.1·i s."""
    timing = {"/fast": (0, 33_333_333), "/late": (150_000_000, 50_000_000)}
    topics = (("/fast", "rgb8"), ("/slow", "rgb8"), ("/late", "jpeg"))
    write_bag(
        tmp_path / "rates" / "run_1",
        kind="mcap",
        topics=topics,
        frames=lambda number, t: np.full((8, 8, 3), (60 * number, 8 * t, 7), np.uint8),
        count=10,
        timing=timing,
    )
    trajectory = load_trajectory(tmp_path / "rates" / "run_1", task="t")
    assert {view: len(trajectory.views[view]) for view in trajectory.views} == {
        "/fast": 10,
        "/late": 10,
        "/slow": 10,
    }
    assert trajectory.fps == pytest.approx(10.0)
    expected = {
        "/slow": list(range(10)),
        "/fast": [3 * i for i in range(10)],
        "/late": [0, 0, *range(1, 17, 2)],
    }
    bag = BagFile(tmp_path / "rates" / "run_1")
    for topic, _ in topics:
        frames = trajectory.views[topic]
        messages = [frames[i].source.index for i in range(10)]
        assert messages == expected[topic], topic
        stamps = [int(bag.topics[topic].times[m]) for m in messages]
        start, period = timing.get(topic, (0, 100_000_000))
        assert stamps == [START_NS + start + m * period for m in messages]
        assert all(
            stamp <= START_NS + i * 100_000_000 or m == 0
            for i, (stamp, m) in enumerate(zip(stamps, messages, strict=True))
        )
        read = [round(frames[i].load()[0, 0, 1] / 8) for i in (0, 5, 9)]  # each message's own t
        assert read == [messages[i] for i in (0, 5, 9)]


def test_a_bare_mcap_file_is_a_bag(tmp_path: Path) -> None:
    bags = tmp_path / "bags"
    write_bag(bags / "run_07.mcap", kind="mcap_file", topics=ENCODINGS[:2], frames=frame, count=4)
    write_bag(bags / "run_08", kind="mcap", topics=ENCODINGS[:2], frames=frame, count=4)
    assert sorted(p.name for p in bags.iterdir()) == ["run_07.mcap", "run_08"]
    dataset = load_dataset(bags, task="pick_cube")
    assert dataset.layout == "rosbag" and [t.episode for t in dataset] == ["run_07", "run_08"]
    assert dataset.skipped == []
    trajectory = load_trajectory(bags, key="run_07", task="pick_cube")
    assert np.array_equal(trajectory.views["/cam_left/image_raw"][3].load(), frame(1, 3))
    reference = trajectory.views["/cam_left/image_raw"][3].reference
    assert reference == f"{bags / 'run_07.mcap'}#topic=/cam_left/image_raw&message=3"
    assert np.array_equal(read_frame(reference), frame(1, 3))


def test_open_bags_are_bounded(tmp_path: Path) -> None:
    from robofailring.data.layouts import rosbag as layout_rosbag

    for number in range(12):
        write_bag(
            tmp_path / "bags" / f"run_{number}", kind="mcap", topics=ENCODINGS[:1], frames=frame, count=2
        )
    dataset = load_dataset(tmp_path / "bags", task="t")
    for trajectory in dataset:
        trajectory.views["/cam_front/image_raw"][1].load()
    assert len(layout_rosbag._OPEN) <= layout_rosbag._OPEN_LIMIT
    opened = [
        bag for bag in layout_rosbag._BAGS.values() if isinstance(bag, BagFile) and bag._reader is not None
    ]
    assert len(opened) <= layout_rosbag._OPEN_LIMIT
