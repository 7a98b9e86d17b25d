"""Small LeRobot datasets written the way lerobot 0.4.x writes them (pyarrow + PyAV), for tests and bench.

v3.0: `meta/info.json`, `meta/tasks.parquet` (task string as the pandas index), episodes in
`meta/episodes/chunk-000/file-000.parquet`, frame rows in `data/chunk-000/file-000.parquet`, and one
mp4 per camera shared by all episodes (`videos/<key>/chunk-000/file-000.mp4`, episode e starting at
`from_timestamp`). v2.1: `meta/episodes.jsonl`, `meta/tasks.jsonl`, one parquet and one mp4 per
camera per episode. Video: AV1 (libsvtav1, keyframe every 2 frames, yuv420p) as lerobot's default,
or H.264 (libx264).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from fractions import Fraction
from pathlib import Path

import av
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

FrameFn = Callable[[int, int, int], np.ndarray]  # (episode, camera, t) -> RGB


def scene(episode: int, camera: int, t: int, size: int = 64) -> np.ndarray:
    """A smooth frame (codecs keep it close): shaded background, a moving square per episode/camera."""
    rows = np.linspace(0.5, 1.0, size, dtype=np.float32)[:, None, None]
    image = np.broadcast_to(np.array([60 + 40 * camera, 110, 150], np.float32) * rows, (size, size, 3)).copy()
    side = size // 4
    top = (size // 8 + 3 * t + 5 * episode) % (size - side)
    left = (size // 8 + 7 * camera + 2 * t) % (size - side)
    image[top : top + side, left : left + side] = (230, 200 - 30 * camera, 40 + 20 * episode)
    return image.astype(np.uint8)


def encode_video(path: Path, frames: Sequence[np.ndarray], fps: int, codec: str = "av1") -> None:
    """Encode RGB frames the way lerobot does: libsvtav1 with g=2 (or libx264), yuv420p."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), "w") as container:
        if codec == "av1":
            stream = container.add_stream("libsvtav1", rate=fps)
            stream.options = {"g": "2", "crf": "30", "preset": "12"}
        else:
            stream = container.add_stream("libx264", rate=fps)
            stream.options = {"g": "2", "crf": "23"}
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


def _features(cameras: Sequence[str], size: int, fps: int, codec: str) -> dict[str, object]:
    features: dict[str, object] = {
        f"observation.images.{camera}": {
            "dtype": "video",
            "shape": [size, size, 3],
            "names": ["height", "width", "channels"],
            "info": {
                "video.height": size,
                "video.width": size,
                "video.codec": "av1" if codec == "av1" else "h264",
                "video.pix_fmt": "yuv420p",
                "video.is_depth_map": False,
                "video.fps": fps,
                "video.channels": 3,
                "has_audio": False,
            },
        }
        for camera in cameras
    }
    # names as lerobot 0.4 writes them (a list) and as v2.1 datasets often do (a dict of one list)
    features["observation.state"] = {"dtype": "float32", "shape": [2], "names": ["time", "episode"]}
    features["action"] = {"dtype": "float32", "shape": [3], "names": {"motors": ["x", "y", "gripper"]}}
    for name, dtype in (
        ("timestamp", "float32"),
        ("frame_index", "int64"),
        ("episode_index", "int64"),
        ("index", "int64"),
        ("task_index", "int64"),
    ):
        features[name] = {"dtype": dtype, "shape": [1], "names": None}
    return features


def signal_action(episode: int, t: int) -> tuple[float, float, float]:
    """The `action` row the writers store for frame t of an episode (exact in float32)."""
    return (0.5 * t, -float(t), float(episode % 2))


def _frame_table(lengths: Sequence[int], task_of: Sequence[int], fps: int, first: int = 0) -> pa.Table:
    rows: dict[str, list[object]] = {
        k: []
        for k in (
            "observation.state",
            "action",
            "timestamp",
            "frame_index",
            "episode_index",
            "index",
            "task_index",
        )
    }
    index = first
    for episode, length in enumerate(lengths):
        for t in range(length):
            rows["observation.state"].append([float(t), float(episode)])
            rows["action"].append(list(signal_action(episode, t)))
            rows["timestamp"].append(t / fps)
            rows["frame_index"].append(t)
            rows["episode_index"].append(episode)
            rows["index"].append(index)
            rows["task_index"].append(task_of[episode])
            index += 1
    return pa.table(
        {
            "observation.state": pa.array(rows["observation.state"], pa.list_(pa.float32())),
            "action": pa.array(rows["action"], pa.list_(pa.float32(), 3)),
            "timestamp": pa.array(rows["timestamp"], pa.float32()),
            **{
                k: pa.array(rows[k], pa.int64())
                for k in ("frame_index", "episode_index", "index", "task_index")
            },
        }
    )


def write_lerobot_v3(
    root: Path,
    *,
    lengths: Sequence[int] = (12, 9, 15),
    tasks: Sequence[str] = ("pick up the cube", "stack the cube", "pick up the cube"),
    cameras: Sequence[str] = ("front", "top", "wrist"),
    size: int = 64,
    fps: int = 10,
    codec: str = "av1",
    frame: FrameFn | None = None,
    shuffled: bool = False,
) -> Path:
    """A LeRobot v3.0 dataset: every camera's episodes concatenated into one shared mp4 (`shuffled`: the
    data parquet's frame rows in a random order, as a dataset edited or merged by other tools may have them)."""
    make = frame or (lambda e, c, t: scene(e, c, t, size))
    unique = list(dict.fromkeys(tasks))
    task_of = [unique.index(task) for task in tasks]
    total = sum(lengths)
    (root / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    info = {
        "codebase_version": "v3.0",
        "robot_type": "so101",
        "total_episodes": len(lengths),
        "total_frames": total,
        "total_tasks": len(unique),
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 500,
        "fps": fps,
        "splits": {"train": f"0:{len(lengths)}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": _features(cameras, size, fps, codec),
    }
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    pq.write_table(
        pa.table({"task_index": pa.array(range(len(unique)), pa.int64()), "__index_level_0__": unique}),
        root / "meta" / "tasks.parquet",
    )
    (root / "data" / "chunk-000").mkdir(parents=True)
    table = _frame_table(lengths, task_of, fps)
    if shuffled:
        table = table.take(np.random.default_rng(0).permutation(table.num_rows))
    pq.write_table(table, root / "data" / "chunk-000" / "file-000.parquet")
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(int)
    episodes: dict[str, list[object]] = {
        "episode_index": list(range(len(lengths))),
        "tasks": [[task] for task in tasks],
        "length": list(lengths),
        "data/chunk_index": [0] * len(lengths),
        "data/file_index": [0] * len(lengths),
        "dataset_from_index": [int(s) for s in starts],
        "dataset_to_index": [int(s + n) for s, n in zip(starts, lengths, strict=True)],
    }
    for c, camera in enumerate(cameras):
        key = f"observation.images.{camera}"
        images = [make(e, c, t) for e, length in enumerate(lengths) for t in range(length)]
        encode_video(root / "videos" / key / "chunk-000" / "file-000.mp4", images, fps, codec)
        episodes[f"videos/{key}/chunk_index"] = [0] * len(lengths)
        episodes[f"videos/{key}/file_index"] = [0] * len(lengths)
        episodes[f"videos/{key}/from_timestamp"] = [float(s) / fps for s in starts]
        episodes[f"videos/{key}/to_timestamp"] = [
            float(s + n) / fps for s, n in zip(starts, lengths, strict=True)
        ]
    episodes["meta/episodes/chunk_index"] = [0] * len(lengths)
    episodes["meta/episodes/file_index"] = [0] * len(lengths)
    pq.write_table(pa.table(episodes), root / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    return root


def write_lerobot_v21(
    root: Path,
    *,
    lengths: Sequence[int] = (8, 11),
    tasks: Sequence[str] = ("open the drawer", "close the drawer"),
    cameras: Sequence[str] = ("front", "wrist"),
    size: int = 64,
    fps: int = 15,
    codec: str = "h264",
    frame: FrameFn | None = None,
    shuffled: bool = False,
) -> Path:
    """A LeRobot v2.1 dataset: one parquet per episode, one mp4 per episode and camera (`shuffled`: each
    episode's frame rows in a random order)."""
    make = frame or (lambda e, c, t: scene(e, c, t, size))
    unique = list(dict.fromkeys(tasks))
    (root / "meta").mkdir(parents=True)
    info = {
        "codebase_version": "v2.1",
        "robot_type": "koch",
        "total_episodes": len(lengths),
        "total_frames": sum(lengths),
        "total_tasks": len(unique),
        "total_videos": len(lengths) * len(cameras),
        "total_chunks": 1,
        "chunks_size": 1000,
        "fps": fps,
        "splits": {"train": f"0:{len(lengths)}"},
        "data_path": "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
        "video_path": "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4",
        "features": _features(cameras, size, fps, codec),
    }
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    (root / "meta" / "tasks.jsonl").write_text(
        "".join(json.dumps({"task_index": i, "task": task}) + "\n" for i, task in enumerate(unique))
    )
    (root / "meta" / "episodes.jsonl").write_text(
        "".join(
            json.dumps({"episode_index": e, "tasks": [tasks[e]], "length": n}) + "\n"
            for e, n in enumerate(lengths)
        )
    )
    (root / "data" / "chunk-000").mkdir(parents=True)
    first = 0
    for e, length in enumerate(lengths):
        table = _frame_table([0] * e + [length], [unique.index(t) for t in tasks[: e + 1]], fps, first)
        if shuffled:
            table = table.take(np.random.default_rng(e).permutation(table.num_rows))
        pq.write_table(table, root / "data" / "chunk-000" / f"episode_{e:06d}.parquet")
        first += length
        for c, camera in enumerate(cameras):
            path = root / "videos" / "chunk-000" / f"observation.images.{camera}" / f"episode_{e:06d}.mp4"
            encode_video(path, [make(e, c, t) for t in range(length)], fps, codec)
    return root
