"""LeRobot datasets (v3.0 and v2.1) read without the `lerobot` package (it pins an old rerun-sdk).

`meta/info.json` gives the version, fps, paths and features; episodes and tasks come from
parquet (v3.0) or JSON lines (v2.1); per-frame timestamps from the data parquet. Each
`observation.images.<name>` video feature is a view `<name>`, decoded lazily by timestamp with
the shared PyAV reader: frame i of an episode is at `from_timestamp + timestamp_i` of its
(possibly shared) mp4. Every other numeric feature (`observation.state`, `action`, …) is a signal
read on demand (`robofailring.data.layouts.lerobot_signals`), and each frame's `timestamp` is kept. The
episode's task string is the task; trajectories are keyed `episode_<index>`; outcome and symbol come
from a labels file.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.layouts.lerobot_signals import episode_signals, signal_features
from robofailring.data.layouts.registry import Layout, register
from robofailring.data.model import Frame, Skipped, Trajectory
from robofailring.data.video import VideoFrames, open_video
from robofailring.errors import DataError, describe
from robofailring.extras import needs_extra
from robofailring.jsontext import parse_json

INFO: Final[str] = "meta/info.json"
IMAGE_PREFIX: Final[str] = "observation.images."
_FRAME_COLUMNS: Final[tuple[str, ...]] = ("episode_index", "frame_index", "timestamp")


def is_lerobot(root: Path) -> bool:
    return (Path(root) / INFO).is_file()


def read_info(root: Path) -> dict[str, Any]:
    path = Path(root) / INFO
    try:
        text = path.read_bytes()
    except OSError as error:
        raise DataError(f"cannot read LeRobot info {path}: {error}") from error
    info = parse_json(text, source=f"LeRobot info {path}")
    required = ("codebase_version", "fps", "features")
    for key in required:
        if not isinstance(info, dict) or key not in info:
            raise DataError(f"LeRobot info {path} lacks {key!r}")
    for key, valid, expected in _INFO_TYPES:
        if key in info and (info[key] is not None or key in required) and not valid(info[key]):
            raise DataError(f"LeRobot info {path}: {key!r} must be {expected}, not {info[key]!r}")
    return dict(info)


def _positive(value: Any) -> bool:
    return (
        isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0
    )


_INFO_TYPES: Final[tuple[tuple[str, Callable[[Any], bool], str], ...]] = (
    ("codebase_version", lambda v: isinstance(v, str), "a version string such as 'v3.0'"),
    ("fps", _positive, "a positive number"),
    (
        "features",
        lambda v: isinstance(v, dict) and all(isinstance(f, dict) for f in v.values()),
        "an object of feature objects",
    ),
    ("chunks_size", lambda v: _positive(v) and isinstance(v, int), "a positive whole number"),
    ("data_path", lambda v: isinstance(v, str), "a path template string"),
    ("video_path", lambda v: isinstance(v, str), "a path template string"),
)


def _path(root: Path, template: str, **keys: object) -> Path:
    """`root / template.format(**keys)`; a template that does not format names info.json."""
    try:
        return root / template.format(**keys)
    except (KeyError, IndexError, ValueError, AttributeError, TypeError) as error:
        raise DataError(
            f"{root / INFO}: path template {template!r} does not format with {sorted(keys)} ({error!r})"
        ) from error


def _exists(file: Path) -> bool:
    """Whether a file is there; a path the system refuses to look up (too long) is not."""
    try:
        return file.is_file()
    except OSError:
        return False


def _read_table(path: Path, columns: Sequence[str] | None = None) -> dict[str, list[Any]]:
    """Columns of a parquet file as Python lists; a missing file or column names both."""
    with needs_extra("video"):
        import pyarrow.parquet as pq

    try:
        schema_names = pq.read_schema(path).names
    except (OSError, ValueError) as error:
        raise DataError(f"cannot read parquet file {path}: {error}") from error
    if columns is not None:
        missing = [c for c in columns if c not in schema_names]
        if missing:
            raise DataError(
                f"parquet file {path} lacks column {missing[0]!r} (it has: {', '.join(schema_names)})"
            )
    try:
        table = pq.read_table(path, columns=list(columns) if columns is not None else None)
    except (OSError, ValueError) as error:
        raise DataError(f"cannot read parquet file {path}: {error}") from error
    return {name: table.column(name).to_pylist() for name in table.column_names}


def _read_jsonl(path: Path) -> list[dict[str, Any]]:
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise DataError(f"cannot read {path}: {describe(error)}") from error
    rows = []
    for number, line in enumerate(lines, 1):
        if line.strip():
            rows.append(parse_json(line, source=f"{path}:{number}"))
    return rows


def lerobot_trajectories(root: Path) -> tuple[list[Trajectory], list[Skipped]]:
    """Every episode of a LeRobot dataset (unlabelled), and the features that are not read as views."""
    root = Path(root)
    info = read_info(root)
    version = str(info["codebase_version"])
    features: dict[str, Any] = info["features"]
    cameras = {
        key: key[len(IMAGE_PREFIX) :]
        for key, f in features.items()
        if f.get("dtype") == "video" and key.startswith(IMAGE_PREFIX)
    }
    skipped = [
        Skipped(root / INFO, f"feature {key!r} ({f.get('dtype')}) is not a video camera: not read")
        for key, f in features.items()
        if f.get("dtype") in ("video", "image") and key not in cameras
    ]
    if not cameras:
        raise DataError(
            f"LeRobot dataset {root} has no video feature named {IMAGE_PREFIX}<camera> in {root / INFO}"
        )
    signals = signal_features(features)
    if version.startswith("v3"):
        trajectories = _v3(root, info, cameras, signals)
    elif version.startswith("v2"):
        trajectories = _v2(root, info, cameras, signals)
    else:
        raise DataError(
            f"LeRobot dataset {root}: codebase_version {version!r}; this reader knows v2.1 and v3.0"
        )
    return trajectories, skipped


def _timestamps(paths: Sequence[Path]) -> dict[int, np.ndarray]:
    """Per episode, its frames' timestamps in frame order, from the data parquet files."""
    by_episode: dict[int, list[tuple[int, float]]] = {}
    for path in paths:
        table = _read_table(path, _FRAME_COLUMNS)
        try:
            for episode, frame, stamp in zip(*(table[c] for c in _FRAME_COLUMNS), strict=True):
                by_episode.setdefault(int(episode), []).append((int(frame), float(stamp)))
        except (TypeError, ValueError, OverflowError) as error:
            raise DataError(
                f"parquet file {path}: a frame row has no valid {_FRAME_COLUMNS} ({error})"
            ) from error
    return {
        episode: np.asarray([stamp for _, stamp in sorted(rows)], dtype=np.float64)
        for episode, rows in by_episode.items()
    }


def _task_of(tasks: Any, where: str) -> str:
    if isinstance(tasks, str) and tasks:
        return tasks
    if isinstance(tasks, list) and tasks and all(isinstance(t, str) for t in tasks):
        return " | ".join(tasks)
    raise DataError(f"{where}: no task string (tasks = {tasks!r})")


@dataclass(frozen=True)
class _Episode:
    """What every episode of a dataset shares: its root, fps and signal features."""

    root: Path
    fps: float
    signals: dict[str, tuple[str, ...]]


def _trajectory(
    shared: _Episode,
    index: int,
    task: str,
    views: dict[str, VideoFrames],
    length: int,
    where: str,
    *,
    stamps: np.ndarray,
    data: Sequence[Path],
) -> Trajectory:
    for view, frames in views.items():
        if len(frames) != length:
            raise DataError(
                f"{where}: episode {index} has length {length} but {len(frames)} frame rows for {view}"
            )
    return Trajectory(
        task=task,
        episode=f"episode_{index}",
        views=dict[str, Sequence[Frame]](views),
        source=shared.root,
        fps=shared.fps,
        signals=episode_signals(shared.signals, data, index),
        timestamps=stamps,
    )


def _v3(
    root: Path, info: dict[str, Any], cameras: dict[str, str], signals: dict[str, tuple[str, ...]]
) -> list[Trajectory]:
    episode_files = sorted((root / "meta" / "episodes").glob("chunk-*/file-*.parquet"))
    if not episode_files:
        raise DataError(f"LeRobot v3.0 dataset {root} has no meta/episodes/chunk-*/file-*.parquet")
    video_path: str = info.get("video_path") or ""
    if "{video_key}" not in video_path:
        raise DataError(f"{root / INFO}: video_path {video_path!r} lacks {{video_key}}")
    data_files = sorted((root / "data").glob("chunk-*/file-*.parquet"))
    if not data_files:
        raise DataError(f"LeRobot v3.0 dataset {root} has no data/chunk-*/file-*.parquet")
    stamps = _timestamps(data_files)
    shared = _Episode(root, float(info["fps"]), signals)
    trajectories = []
    for path in episode_files:
        columns = ["episode_index", "tasks", "length"]
        for key in cameras:
            columns += [f"videos/{key}/{c}" for c in ("chunk_index", "file_index", "from_timestamp")]
        table = _read_table(path, columns)
        for row in range(len(table["episode_index"])):
            trajectories.append(
                _v3_episode(shared, path, table, row, cameras, video_path, stamps, data_files)
            )
    return sorted(trajectories, key=lambda t: int(t.episode.split("_")[-1]))


def _v3_episode(
    shared: _Episode,
    path: Path,
    table: dict[str, list[Any]],
    row: int,
    cameras: dict[str, str],
    video_path: str,
    stamps: dict[int, np.ndarray],
    data: Sequence[Path],
) -> Trajectory:
    """Row `row` of the episode table `path`; a missing or mistyped value names the file and row."""
    try:
        index = int(table["episode_index"][row])
        length = int(table["length"][row])
        videos = {
            key: tuple(
                kind(table[f"videos/{key}/{column}"][row])
                for column, kind in (("chunk_index", int), ("file_index", int), ("from_timestamp", float))
            )
            for key in cameras
        }
    except (TypeError, ValueError, OverflowError) as error:
        raise DataError(f"{path} row {row}: a missing or mistyped value ({error})") from error
    where = f"{path} (episode {index})"
    root = shared.root
    if index not in stamps:
        raise DataError(f"{where}: no frame rows for this episode in {root / 'data'}")
    views = {}
    for key, view in cameras.items():
        chunk, number, start = videos[key]
        file = _path(root, video_path, video_key=key, chunk_index=chunk, file_index=number)
        if not _exists(file):
            raise DataError(f"{where}: video {file} is missing")
        views[view] = VideoFrames(open_video(file), start + stamps[index])
    task = _task_of(table["tasks"][row], where)
    return _trajectory(shared, index, task, views, length, where, stamps=stamps[index], data=data)


def _v2(
    root: Path, info: dict[str, Any], cameras: dict[str, str], signals: dict[str, tuple[str, ...]]
) -> list[Trajectory]:
    episodes = _read_jsonl(root / "meta" / "episodes.jsonl")
    data_path: str = info.get("data_path") or ""
    video_path: str = info.get("video_path") or ""
    chunks = int(info.get("chunks_size") or 1000)
    shared = _Episode(root, float(info["fps"]), signals)
    trajectories = []
    for number, record in enumerate(episodes, 1):
        where = f"{root / 'meta' / 'episodes.jsonl'}:{number}"
        try:
            index = int(record["episode_index"])
            length = int(record["length"])
        except (KeyError, TypeError, ValueError, OverflowError) as error:
            raise DataError(f"{where}: bad episode record ({error!r})") from error
        chunk = index // chunks
        data = _path(root, data_path, episode_chunk=chunk, episode_index=index)
        stamps = _timestamps([data]).get(index)
        if stamps is None:
            raise DataError(f"{data}: no frame rows for episode {index}")
        views = {}
        for key, view in cameras.items():
            file = _path(root, video_path, episode_chunk=chunk, video_key=key, episode_index=index)
            if not _exists(file):
                raise DataError(f"{where}: video {file} is missing")
            views[view] = VideoFrames(open_video(file), stamps)
        task = _task_of(record.get("tasks"), where)
        trajectories.append(
            _trajectory(shared, index, task, views, length, where, stamps=stamps, data=[data])
        )
    return trajectories


def _read(root: Path, *, task: str | None = None) -> tuple[list[Trajectory], list[Skipped]]:
    return lerobot_trajectories(root)


LAYOUT: Final = register(
    Layout(
        name="lerobot",
        detect=is_lerobot,
        read=_read,
        help="a LeRobot dataset (v2.1 or v3.0: meta/info.json, parquet, one mp4 per camera)",
        listed=4,
        detect_order=20,  # meta/info.json says what it is
    )
)
