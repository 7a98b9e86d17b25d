"""The peer set written as a LeRobot v3.0 dataset, the layout a LeRobot user has: one shared mp4 per camera
(AV1, keyframe every 2 frames, as lerobot 0.4 writes them), the data parquet with `observation.state`
and `action` (the commanded joint positions and gripper) per frame, each dimension named in
`meta/info.json`, and labels files by `episode_index` (docs/bench_peer.md).

Two states (`STATES`): `recorded`, what a robot records (joint positions and velocities, finger joints,
gripper width, hand pose), and `privileged`, the set before it, which adds the hand's offset from the
task's goal (the simulator's knowledge, no robot's) and a `goal` column.

Called by bench/bench_peer.py in the project's venv (PyAV, pyarrow) on the episode folders and the
`signals.npz` that bench/peer_generate.py writes; the library then reads it with its own LeRobot
reader, as a user's dataset.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

import av
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from robofailring.data.images import read_image

VIEWS = ("hand", "base", "render")
#: observation.state's signals, in this order, per kind of state
STATES: dict[str, tuple[str, ...]] = {
    "recorded": ("joint_positions", "joint_velocities", "gripper_width", "ee_pose"),
    "privileged": ("joint_positions", "gripper_width", "ee_pose", "ee_to_goal"),
}
LABELS = ("episode_index", "task", "outcome", "symbol", "onset_frame", "description", "split")


def _names(signal_names: dict[str, list[str]], signals: Sequence[str]) -> list[str]:
    return [f"{name}.{dim}" for name in signals for dim in signal_names[name]]


def _video(path: Path, frames: list[np.ndarray], fps: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libsvtav1", rate=fps)
        stream.options = {"g": "2", "crf": "30", "preset": "12"}
        stream.pix_fmt = "yuv420p"
        stream.height, stream.width = frames[0].shape[:2]
        stream.time_base = Fraction(1, fps)
        for index, image in enumerate(frames):
            frame = av.VideoFrame.from_ndarray(image, format="rgb24")
            frame.pts = index
            for packet in stream.encode(frame):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)


def export_lerobot(
    episodes: Path,
    runs: list[dict[str, Any]],
    out: Path,
    *,
    fps: int,
    signal_names: dict[str, list[str]],
    state: str = "recorded",
) -> tuple[Path, Path, Path]:
    """`runs` (the peer set's, with `episode`, `task`, `split`) as a LeRobot v3.0 dataset at `out` with the
    `state` of `STATES`; its labels file and the one with the ID halves exchanged."""
    tasks = sorted({run["task"] for run in runs})
    signals_in = STATES[state]
    columns = ("observation.state", "action", "timestamp") + (("goal",) if state == "privileged" else ())
    rows: dict[str, list[Any]] = {k: [] for k in columns}
    index_rows: dict[str, list[int]] = {
        k: [] for k in ("frame_index", "episode_index", "index", "task_index")
    }
    frames: dict[str, list[np.ndarray]] = {view: [] for view in VIEWS}
    table: dict[str, list[Any]] = {"episode_index": [], "tasks": [], "length": []}
    starts: list[int] = []
    for number, run in enumerate(runs):
        folder = episodes / run["episode"]
        with np.load(folder / "signals.npz", allow_pickle=False) as stored:
            signals = {name: np.asarray(stored[name], np.float32) for name in stored.files}
        length = len(signals["action"])
        starts.append(len(index_rows["index"]))
        for view in VIEWS:
            frames[view] += [read_image(folder / view / f"{t}.png") for t in range(length)]
        values = np.concatenate([signals[name] for name in signals_in], axis=1)
        for t in range(length):
            rows["observation.state"].append(values[t].tolist())
            rows["action"].append(signals["action"][t].tolist())
            if "goal" in rows:
                rows["goal"].append(signals["goal"][t].tolist())
            rows["timestamp"].append(t / fps)
            index_rows["frame_index"].append(t)
            index_rows["episode_index"].append(number)
            index_rows["index"].append(len(index_rows["index"]))
            index_rows["task_index"].append(tasks.index(run["task"]))
        table["episode_index"].append(number)
        table["tasks"].append([run["task"]])
        table["length"].append(length)
    (out / "data" / "chunk-000").mkdir(parents=True)
    (out / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    data = {
        name: pa.array(values, pa.list_(pa.float32(), len(values[0])))
        for name, values in rows.items()
        if name != "timestamp"
    }
    data["timestamp"] = pa.array(rows["timestamp"], pa.float32())
    data |= {name: pa.array(values, pa.int64()) for name, values in index_rows.items()}
    pq.write_table(pa.table(data), out / "data" / "chunk-000" / "file-000.parquet")
    for view in VIEWS:
        key = f"observation.images.{view}"
        _video(out / "videos" / key / "chunk-000" / "file-000.mp4", frames[view], fps)
        table[f"videos/{key}/chunk_index"] = [0] * len(runs)
        table[f"videos/{key}/file_index"] = [0] * len(runs)
        table[f"videos/{key}/from_timestamp"] = [start / fps for start in starts]
        table[f"videos/{key}/to_timestamp"] = [
            (s + n) / fps for s, n in zip(starts, table["length"], strict=True)
        ]
    pq.write_table(pa.table(table), out / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    pq.write_table(
        pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "__index_level_0__": tasks}),
        out / "meta" / "tasks.parquet",
    )
    size = frames[VIEWS[0]][0].shape[0]
    features: dict[str, Any] = {
        f"observation.images.{view}": {
            "dtype": "video",
            "shape": [size, size, 3],
            "names": ["height", "width", "channels"],
            "info": {"video.codec": "av1", "video.pix_fmt": "yuv420p", "video.fps": fps},
        }
        for view in VIEWS
    }
    features["observation.state"] = {"dtype": "float32", "shape": [len(rows["observation.state"][0])],
                                     "names": _names(signal_names, signals_in)}  # fmt: skip
    features["action"] = {
        "dtype": "float32",
        "shape": [len(rows["action"][0])],
        "names": signal_names["action"],
    }
    if "goal" in rows:
        features["goal"] = {"dtype": "float32", "shape": [3], "names": signal_names["goal"]}
    for name in ("timestamp",):
        features[name] = {"dtype": "float32", "shape": [1], "names": None}
    for name in index_rows:
        features[name] = {"dtype": "int64", "shape": [1], "names": None}
    info = {
        "codebase_version": "v3.0",
        "robot_type": "panda",
        "total_episodes": len(runs),
        "total_frames": len(index_rows["index"]),
        "total_tasks": len(tasks),
        "chunks_size": 1000,
        "fps": fps,
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": features,
    }
    (out / "meta" / "info.json").write_text(json.dumps(info, indent=2), encoding="utf-8")
    exchange = {"train": "test", "test": "train", "ood": "ood"}
    labels, swapped = out / "labels.csv", out / "labels-swapped.csv"
    for path, split_of in ((labels, lambda s: s), (swapped, lambda s: exchange[s])):
        with path.open("w", newline="", encoding="utf-8") as handle:
            writer = csv.DictWriter(handle, fieldnames=LABELS, extrasaction="ignore")
            writer.writeheader()
            for number, run in enumerate(runs):
                writer.writerow({**run, "episode_index": number, "split": split_of(run["split"])})
    return out, labels, swapped
