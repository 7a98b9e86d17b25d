"""A LeRobot dataset's signals: every numeric feature of the data parquet that is not a camera or a
frame's bookkeeping (`observation.state`, `action`, `observation.effort`, `next.reward`, …).

Each is read on demand, per episode, from the data parquet files (v3.0: files shared by many
episodes; a file's column is read once and kept while a dataset's episodes are read); its dimensions
are named by the feature's `names` in `meta/info.json` (a list, or LeRobot v2.1's `{"motors": [...]}`).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.signals import Signal, kind_of
from robofailring.errors import DataError
from robofailring.extras import needs_extra

#: Columns of every frame row that say where the row is, not what the robot did.
BOOKKEEPING: Final[frozenset[str]] = frozenset(
    {"timestamp", "frame_index", "episode_index", "index", "task_index"}
)
_NUMERIC: Final[frozenset[str]] = frozenset(
    {"float16", "float32", "float64", "int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "bool"}
)


def signal_features(features: dict[str, Any]) -> dict[str, tuple[str, ...]]:
    """The numeric features that are signals, with their dimension names (empty: unnamed)."""
    return {
        key: _names(feature.get("names"))
        for key, feature in features.items()
        if key not in BOOKKEEPING and str(feature.get("dtype")) in _NUMERIC
    }


def _names(names: object) -> tuple[str, ...]:
    """A feature's `names`: a list of strings, or a dict holding one (`{"motors": [...]}`); else none."""
    if isinstance(names, dict) and len(names) == 1:
        names = next(iter(names.values()))
    if isinstance(names, list) and names and all(isinstance(name, str) for name in names):
        return tuple(names)
    return ()


@dataclass(frozen=True)
class ParquetColumn:
    """One feature's rows for one episode, gathered from the data parquet files that hold them."""

    files: tuple[Path, ...]
    column: str
    episode: int

    def load(self) -> np.ndarray:
        rows: list[np.ndarray] = []
        frames: list[np.ndarray] = []
        for path in self.files:
            episodes, frame_index, values = _column(path, _version(path), self.column)
            mine = episodes == self.episode
            if mine.any():
                rows.append(values[mine])
                frames.append(frame_index[mine])
        if not rows:
            raise DataError(f"{self.reference}: no frame rows for episode {self.episode}")
        order = np.argsort(np.concatenate(frames), kind="stable")
        return np.concatenate(rows)[order]

    @property
    def reference(self) -> str:
        shown = str(self.files[0]) + (f" (+{len(self.files) - 1} files)" if len(self.files) > 1 else "")
        return f"{shown}#column={self.column}&episode={self.episode}"


def _version(path: Path) -> tuple[int, int]:
    try:
        stat = path.stat()
    except OSError as error:
        raise DataError(f"cannot read parquet file {path}: {error.strerror or error}") from error
    return stat.st_mtime_ns, stat.st_size


@functools.lru_cache(maxsize=16)
def _column(path: Path, version: tuple[int, int], column: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(episode_index, frame_index, values) of one data file's column; `version` renews it when the file changes."""
    with needs_extra("video"):
        import pyarrow as pa
        import pyarrow.parquet as pq

    try:
        table = pq.read_table(path, columns=["episode_index", "frame_index", column])
    except (OSError, ValueError, KeyError, pa.ArrowException) as error:
        raise DataError(f"cannot read column {column!r} of parquet file {path}: {error}") from error
    try:
        episodes = np.asarray(table.column("episode_index").to_numpy(), dtype=np.int64)
        frames = np.asarray(table.column("frame_index").to_numpy(), dtype=np.int64)
    except (pa.ArrowException, TypeError, ValueError) as error:
        raise DataError(f"parquet file {path}: episode_index or frame_index is not whole numbers") from error
    return episodes, frames, _values(table.column(column).combine_chunks(), f"{path} column {column!r}")


def _values(array: Any, where: str) -> np.ndarray:
    """A parquet column as an (N, …) array: a list column of equal lengths is (N, D), numbers (N,)."""
    with needs_extra("video"):
        import pyarrow as pa

    if (
        pa.types.is_list(array.type)
        or pa.types.is_fixed_size_list(array.type)
        or pa.types.is_large_list(array.type)
    ):
        if array.null_count:
            raise DataError(f"{where}: {array.null_count} rows have no value")
        lengths = np.asarray(array.value_lengths().to_numpy(zero_copy_only=False))
        if len(lengths) and (lengths != lengths[0]).any():
            raise DataError(f"{where}: rows of {sorted(set(lengths.tolist()))} values (one length expected)")
        flat = np.asarray(array.flatten().to_numpy(zero_copy_only=False))
        return flat.reshape(len(array), int(lengths[0]) if len(lengths) else 0)
    if pa.types.is_integer(array.type) or pa.types.is_floating(array.type) or pa.types.is_boolean(array.type):
        if array.null_count:
            raise DataError(f"{where}: {array.null_count} rows have no value")
        return np.asarray(array.to_numpy(zero_copy_only=False))
    raise DataError(f"{where}: values of type {array.type} are not numbers")


def episode_signals(
    features: dict[str, tuple[str, ...]], files: Sequence[Path], episode: int
) -> dict[str, Signal]:
    """One episode's signals (`signal_features`), each read from `files` when it is wanted."""
    return {
        key: Signal(name=key, kind=kind_of(key), source=ParquetColumn(tuple(files), key, episode), dims=dims)
        for key, dims in features.items()
    }
