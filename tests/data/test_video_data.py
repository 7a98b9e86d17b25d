"""LeRobot datasets (v3.0 AV1, v2.1 H.264) and video episodes, written here and read back pixel-close."""

from __future__ import annotations

import json
import wave
from dataclasses import replace
from fractions import Fraction
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from environment import shared_data
from lerobot_writer import encode_video, scene, signal_action, write_lerobot_v3, write_lerobot_v21
from rrd import columns, properties, rows
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring import (
    CachedEncoder,
    FailureDetector,
    FailureMemory,
    load_dataset,
    load_encoder,
    load_trajectory,
)
from robofailring.data.images import read_image
from robofailring.data.model import LazyFrames
from robofailring.data.video import open_video
from robofailring.errors import DataError

V3_LENGTHS = (12, 9, 15)


@pytest.fixture(scope="module")
def v3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Its data parquet's frame rows shuffled, as tools that edit or merge datasets may leave them: every test
    of it reads frames, signals and timestamps in frame order all the same."""
    return write_lerobot_v3(
        tmp_path_factory.mktemp("lerobot") / "so101_pick", lengths=V3_LENGTHS, shuffled=True
    )


def mean_abs(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(np.int16) - b.astype(np.int16)).mean())


def assert_pixels_close(dataset_root: Path, lengths: tuple[int, ...], cameras: tuple[str, ...]) -> None:
    """Every frame within mean |diff| ≤ 8 of its source, and closer to it than to its neighbours."""
    trajectories = list(load_dataset(dataset_root))
    assert [t.episode for t in trajectories] == [f"episode_{i}" for i in range(len(lengths))]
    for e, trajectory in enumerate(trajectories):
        assert trajectory.view_names == list(cameras) and trajectory.length == lengths[e]
        for c, camera in enumerate(cameras):
            frames = trajectory.views[camera]
            assert len(frames) == lengths[e]
            for t in (*range(lengths[e]), 3, 0):  # in order, then backwards (a seek)
                decoded = frames[t].load()
                assert decoded.shape == (64, 64, 3)
                assert mean_abs(decoded, scene(e, c, t)) <= 8
                for other in (t - 1, t + 1):
                    if 0 <= other < lengths[e]:
                        assert mean_abs(decoded, scene(e, c, t)) < mean_abs(decoded, scene(e, c, other))


def test_lerobot_v3_av1_reads_back_pixel_close(v3: Path) -> None:
    dataset = load_dataset(v3)
    assert dataset.layout == "lerobot" and dataset.skipped == [] and not dataset.labelled
    tasks = [t.task for t in dataset]
    assert tasks == ["pick up the cube", "stack the cube", "pick up the cube"]
    assert {t.fps for t in dataset} == {10.0}
    codec = open_video(v3 / "videos" / "observation.images.front" / "chunk-000" / "file-000.mp4")
    assert codec.count == sum(V3_LENGTHS)  # the container's count: all episodes share the file
    assert_pixels_close(v3, V3_LENGTHS, ("front", "top", "wrist"))


def test_lerobot_v21_h264_reads_back_pixel_close(tmp_path: Path) -> None:
    root = write_lerobot_v21(
        tmp_path / "koch", lengths=(8, 11), shuffled=True
    )  # frames in frame order all the same
    dataset = load_dataset(root)
    assert dataset.layout == "lerobot" and [t.task for t in dataset] == [
        "open the drawer",
        "close the drawer",
    ]
    assert_pixels_close(root, (8, 11), ("front", "wrist"))


def test_labels_build_a_memory_and_replay_a_recording(v3: Path, tmp_path: Path) -> None:
    labels = tmp_path / "labels.csv"
    labels.write_text(
        "episode_index,outcome,symbol\n0,failure,grasp_wp2\n1,success,\n2,failure,wrong_object_wp0\n"
    )
    runner = CliRunner()
    cache = ["--cache-dir", str(tmp_path / "cache")]
    memory = tmp_path / "memory"
    refused = runner.invoke(app, ["build-memory", str(v3), "--out", str(memory), *cache])
    assert refused.exit_code == 2 and "--labels FILE" in refused.output
    built = runner.invoke(
        app, ["build-memory", str(v3), "--out", str(memory), "--labels", str(labels), *cache]
    )
    assert built.exit_code == 0, built.output
    assert "from 6 failure views" in built.output and "2 failure trajectories over 1 tasks" in built.output
    entries = [json.loads(line) for line in (memory / "entries.jsonl").read_text().splitlines()]
    assert {(e["episode"], e["symbol"]) for e in entries} == {
        ("episode_0", "grasp_wp2"),
        ("episode_2", "wrong_object_wp0"),
    }
    # dense, from frame 1 (no onset given) to the end, each entry's image the video frame it says
    first_view = [
        e for e in entries if (e["episode"], e["view"]) == (entries[0]["episode"], entries[0]["view"])
    ]
    assert first_view[0]["frame"] == 1 and (first_view[-1]["frame"], first_view[-1]["length"]) == (11, 12)
    assert all(e["end"].endswith(f"file-000.mp4#frame={e['frame']}") for e in first_view)
    # unlabelled data still replays and detects
    out = tmp_path / "recordings"
    replayed = runner.invoke(
        app,
        [
            "replay",
            str(v3),
            "--memory",
            str(memory),
            "--trajectory",
            "episode_2",
            "--out",
            str(out),
            "--stride",
            "4",
            *cache,
        ],
    )
    assert replayed.exit_code == 0, replayed.output
    (recording,) = out.glob("*.rrd")
    assert [frame for frame, _ in rows(recording, "/camera/front", "EncodedImage:blob")] == list(range(15))
    assert [frame for frame, _ in rows(recording, "/score/front/paper", "Scalars:scalars")] == [0, 4, 8, 12]
    assert properties(recording)["stride"] == 4 and properties(recording)["task"] == "pick up the cube"
    neighbour = rows(recording, "/neighbors/front/0/end", "EncodedImage:blob")  # read back from the mp4
    assert neighbour and neighbour[0][0] == 0
    # the robot's signals on the cameras' timeline, every frame (not only the scored ones), named
    state = rows(recording, "/signals/observation.state", "Scalars:scalars")
    assert [frame for frame, _ in state] == list(range(15))
    assert [list(values) for _, values in state[:3]] == [[0.0, 2.0], [1.0, 2.0], [2.0, 2.0]]
    action = rows(recording, "/signals/action", "Scalars:scalars")
    assert [list(values) for _, values in action][4] == list(signal_action(2, 4))
    assert columns(recording, "/signals/action")["SeriesLines:names"][0] == ["x", "y", "gripper"]
    assert properties(recording)["signals"] == "observation.state (state, 2), action (action, 3)"
    assert not properties(recording).get("signals_not_read")  # every signal was read
    detected = runner.invoke(
        app, ["detect", str(v3), "--memory", str(memory), "--trajectory", "episode_0", "--json", *cache]
    )
    assert detected.exit_code == 0, detected.output
    found = json.loads(detected.stdout)
    assert found["length"] == 12 and found["fps"] == 10.0  # the dataset's rate (write_lerobot_v3's)
    assert found["t_det_s"] == (found["t_det"] / 10.0 if found["t_det"] is not None else None)


def test_stride_scores_every_nth_frame_in_original_frame_numbers(v3: Path, tmp_path: Path) -> None:
    trajectory = load_trajectory(v3, key="episode_2")
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    source = load_dataset(v3)
    failures = [t for t in source if t.episode != "episode_2"]
    failures = [replace(t, symbol="slip_wp1") for t in failures]
    memory, _ = FailureMemory.build(failures, encoder)
    detector = FailureDetector(memory, encoder)
    every = detector.run(trajectory)
    strided = detector.run(trajectory, stride=5)
    assert strided.length == every.length == 15 and strided.stride == 5
    assert list(strided.scored_frames) == [0, 5, 10]
    for view in every.views:
        assert np.allclose(
            strided.similarity[view][[0, 5, 10]], every.similarity[view][[0, 5, 10]], atol=1e-6
        )
        assert np.isnan(strided.similarity[view][[1, 2, 3, 4, 6, 14]]).all()
    peaks = every.max_similarity()
    for delta in sorted(peaks[[0, 5, 10]]):  # t_det is the first *scored* frame over δ, in frame numbers
        expected = next(t for t in (0, 5, 10) if peaks[t] >= delta)
        assert strided.with_delta(float(delta)).t_det == expected
    assert strided.to_dict()["views"]["front"]["similarity"][1] is None


def test_video_episodes_and_the_real_episode_as_mp4(tmp_path: Path) -> None:
    root = tmp_path / "videos"
    for episode, name in enumerate(("pick_cube_grasp_wp2_episode0", "run_7")):
        for c, view in enumerate(("front", "wrist")):
            encode_video(
                root / name / f"{view}.mp4", [scene(episode, c, t) for t in range(10 + episode)], 10, "h264"
            )
    (root / "run_7" / "notes.txt").write_text("operator notes")
    (root / "empty").mkdir()
    with pytest.raises(DataError, match="--task"):
        load_trajectory(root / "run_7")
    dataset = load_dataset(root, task="pick_cube")
    assert dataset.layout == "videos"
    named, plain = list(dataset)
    assert (named.task, named.symbol, named.length) == ("pick_cube", "grasp_wp2", 10)
    assert (plain.task, plain.episode, plain.length) == ("pick_cube", "run_7", 11)
    assert mean_abs(plain.views["wrist"][7].load(), scene(1, 1, 7)) <= 8
    assert {item.path.name for item in dataset.skipped} == {"empty", "notes.txt"}
    pngs = sorted(
        (shared_data("maniskill-failgen-episode") / "front").glob("*.png"), key=lambda p: int(p.stem)
    )
    sources = [read_image(p) for p in pngs]
    encode_video(tmp_path / "real" / "front.mp4", sources, 10, "av1")
    real = load_trajectory(tmp_path / "real", task="FailPickCube-v1")
    assert real.length == len(pngs) == 69
    for t in (0, 30, 68, 12):
        assert mean_abs(real.views["front"][t].load(), sources[t]) <= 8


def test_video_frames_are_cached_by_file_content(v3: Path, tmp_path: Path) -> None:
    trajectory = load_trajectory(v3, key="episode_1")
    frames = list(trajectory.views["top"])
    first = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    vectors = first.encode_frames(frames)
    second = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    again = second.encode_frames(frames)
    assert (second.hits, second.misses) == (len(frames), 0) and np.array_equal(vectors, again)
    assert len({frame.content_key() for frame in frames}) == len(frames)


def test_bad_video_data_names_the_file_or_value(v3: Path, tmp_path: Path) -> None:
    # a corrupt mp4
    broken = tmp_path / "broken" / "ep"
    broken.mkdir(parents=True)
    (broken / "front.mp4").write_bytes(b"\x00\x00\x00\x18ftypisom" + b"garbage" * 50)
    trajectory = load_trajectory(broken, task="pick_cube")
    with pytest.raises(DataError, match=r"front\.mp4"):
        trajectory.views["front"][0].load()
    # a container FFmpeg reads that holds no video (sound saved as .mp4): said, not "tuple index out of range"
    with wave.open(str(broken / "front.mp4"), "wb") as sound:
        sound.setnchannels(1)
        sound.setsampwidth(2)
        sound.setframerate(8000)
        sound.writeframes(bytes(1600))
    with pytest.raises(DataError, match=r"front\.mp4: it holds no video stream 0"):
        len(load_trajectory(broken, task="pick_cube").views["front"])
    # a parquet missing a column
    copy = write_lerobot_v3(tmp_path / "nocol", lengths=(4, 5), tasks=("a", "b"), cameras=("front",))
    data = copy / "data" / "chunk-000" / "file-000.parquet"
    pq.write_table(pq.read_table(data).drop(["timestamp"]), data)
    with pytest.raises(DataError, match=r"file-000\.parquet lacks column 'timestamp'"):
        load_dataset(copy)
    # labels naming an episode that does not exist, and an unknown symbol
    labels = tmp_path / "labels.json"
    labels.write_text(json.dumps([{"episode_index": 7, "outcome": "failure", "symbol": "grasp_wp1"}]))
    with pytest.raises(
        DataError, match=r"labels\.json names episode 'episode_7', which is not in the dataset"
    ):
        load_dataset(v3, labels=labels)
    labels.write_text(json.dumps([{"episode_index": 0, "outcome": "failure", "symbol": "twist_wp1"}]))
    with pytest.raises(DataError, match=r"labels\.json row 1: unknown failure token 'twist'"):
        load_dataset(v3, labels=labels)


def test_video_episodes_take_their_task_from_the_labels(tmp_path: Path) -> None:
    """One camera per episode, names that say nothing: the labels' task column is enough (no --task)."""
    root = tmp_path / "clips"
    for episode in range(3):
        encode_video(
            root / f"clip_{episode}" / "front.mp4", [scene(episode, 0, t) for t in range(6)], 10, "h264"
        )
    labels = tmp_path / "labels.csv"
    labels.write_text(
        "episode,outcome,symbol,task\nclip_0,success,,pick_cube\nclip_1,failure,grasp_wp2,pick_cube\n"
        "clip_2,failure,,push_cube\n"
    )
    dataset = load_dataset(root, labels=labels)
    assert dataset.layout == "videos" and dataset.labelled
    assert [(t.episode, t.task, t.label, t.length) for t in dataset] == [
        ("clip_0", "pick_cube", "success", 6),
        ("clip_1", "pick_cube", "grasp_wp2", 6),
        ("clip_2", "push_cube", "failure", 6),
    ]
    # without labels nothing says the task: an error naming how many episodes, one of them, and the remedies
    with pytest.raises(
        DataError,
        match=r"cannot tell the task of 3 episode\(s\) of .*clips \(videos layout\), e\.g\. 'clip_0': pass --task, or a task column",
    ):
        load_dataset(root)
    # with --task alone the outcome is still unknown: a verb that needs it says so
    untold = load_dataset(root, task="pick_cube")
    assert not untold.labelled and [t.outcome for t in untold] == [None] * 3
    with pytest.raises(DataError, match=r"build-memory needs to know which episodes failed.*--labels"):
        untold.require_labels("build-memory")


def test_video_episodes_take_their_frame_rate_from_the_container(tmp_path: Path) -> None:
    """A clip's rate is the recording's `time` and the seconds of a detection delay (it was None: 10 fps)."""
    root = tmp_path / "clips"
    for episode, fps in enumerate((6, 25)):
        encode_video(
            root / f"clip_{episode}" / "front.mp4", [scene(episode, 0, t) for t in range(8)], fps, "h264"
        )
    labels = tmp_path / "labels.csv"
    labels.write_text(
        "episode,outcome,symbol,task,onset_frame\nclip_0,failure,,pick_cube,2\nclip_1,success,,pick_cube,\n"
    )
    dataset = load_dataset(root, labels=labels)
    assert [(t.episode, t.frame_rate) for t in dataset] == [("clip_0", 6.0), ("clip_1", 25.0)]
    assert load_trajectory(root / "clip_1", task="pick_cube").frame_rate == 25.0
    assert open_video(root / "clip_0" / "front.mp4").fps == 6.0
    # one frame has no rate: None (the recording's default), not a division by zero
    encode_video(tmp_path / "still" / "front.mp4", [scene(0, 0, 0)], 6, "h264")
    assert load_trajectory(tmp_path / "still", task="pick_cube").frame_rate is None
    # a layout's own rate wins (LeRobot's info.json): its views are frames picked by time, without one
    (lerobot,) = load_dataset(
        write_lerobot_v3(tmp_path / "lerobot", lengths=(4,), tasks=("a",), cameras=("front",))
    )
    front = lerobot.views["front"]
    assert isinstance(front, LazyFrames) and front.fps is None
    assert (lerobot.fps, lerobot.frame_rate) == (10.0, 10.0)
    runner = CliRunner()
    cache = ["--cache-dir", str(tmp_path / "cache")]
    memory = tmp_path / "memory"
    built = runner.invoke(
        app, ["build-memory", str(root), "--labels", str(labels), "--out", str(memory), *cache]
    )
    assert built.exit_code == 0, built.output
    out = tmp_path / "recordings"
    replayed = runner.invoke(
        app,
        ["replay", str(root), "--memory", str(memory), "--labels", str(labels), "--out", str(out), *cache],
    )
    assert replayed.exit_code == 0, replayed.output
    rates = {properties(r)["episode"]: properties(r)["fps"] for r in out.glob("*.rrd")}
    assert rates == {"clip_0": 6.0, "clip_1": 25.0}


def _out_of_order(path: Path, order: list[int]) -> None:
    """An intra-only (MJPEG) video whose packets, in decoding order, carry the timestamps `order`: its
    frames decode out of timestamp order, as some phones' HEVC clips do. Frame pts p is grey 20 + 25 p."""
    import av

    with av.open(str(path), "w") as out:
        stream = out.add_stream("mjpeg", rate=10)
        stream.width, stream.height, stream.pix_fmt = 48, 32, "yuvj420p"
        stream.time_base = Fraction(1, 10)
        for dts, pts in enumerate(order):
            image = np.full((32, 48, 3), 20 + 25 * pts, np.uint8)
            for packet in stream.encode(av.VideoFrame.from_ndarray(image, format="rgb24")):
                packet.pts, packet.dts = pts, dts - 1  # dts ≤ pts, increasing
                out.mux(packet)


@pytest.mark.parametrize("suffix", [".mp4", ".mkv"])
def test_frames_that_decode_out_of_timestamp_order_are_read_by_their_timestamp(
    tmp_path: Path, suffix: str
) -> None:
    """Frame i is the frame with the i-th timestamp, in any order of asking: the first frame decoded past
    the timestamp is another frame, and in an MP4 a seek (by decoding time) can land past the frame."""
    path = tmp_path / f"clip{suffix}"
    _out_of_order(path, [0, 2, 1, 3, 5, 4, 6, 8, 7])
    for asked in (list(range(9)), [5, 1, 8, 0, 4, 2, 3, 7, 6], [8, 7, 6, 5, 4, 3, 2, 1, 0]):
        video = open_video(path)  # a fresh reader for each order
        assert video.count == 9
        greys = {i: float(video.decode(i).mean()) for i in asked}
        assert all(abs(greys[i] - (20 + 25 * i)) < 3 for i in asked), greys


def test_a_clip_with_a_display_rotation_is_read_as_players_show_it(tmp_path: Path) -> None:
    """A phone's portrait clip is stored landscape with a display matrix: its frames are read turned as
    FFmpeg shows them (the reference here), not as stored, and their cache keys say so."""
    import subprocess

    from environment import require_ffmpeg

    require_ffmpeg()
    stored = tmp_path / "stored.mp4"
    encode_video(stored, [scene(0, 0, t) for t in range(4)], 10, "h264")
    turned = tmp_path / "turned.mp4"
    for how in (
        ["-display_rotation", "90", "-i", str(stored)],
        ["-i", str(stored), "-metadata:s:v:0", "rotate=90"],
    ):
        subprocess.run(["ffmpeg", "-loglevel", "error", "-y", *how, "-c", "copy", str(turned)], check=False)
        if turned.exists():
            break
    assert turned.exists(), "ffmpeg wrote no rotated copy"
    shown = subprocess.run(
        ["ffmpeg", "-loglevel", "error", "-i", str(turned), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
        capture_output=True,
        check=True,
    ).stdout
    plain, video = open_video(stored).decode(2), open_video(turned)
    height, width = plain.shape[1], plain.shape[0]  # turned a quarter
    expected = np.frombuffer(shown, np.uint8).reshape(-1, height, width, 3)
    assert video.count == 4 == len(expected)
    for index in (0, 2, 3):
        image = video.decode(index)
        assert image.shape == (height, width, 3)
        assert np.abs(image.astype(int) - expected[index].astype(int)).mean() < 2.0
    assert np.array_equal(video.decode(2), np.rot90(plain, 1))  # the same pixels, a quarter turn
