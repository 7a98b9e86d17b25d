"""Reading recordings back: the one place tests open an `.rrd` with rerun.chunk.RrdReader."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

from rfr_viz.viewer.rrd import NO_FOOTER


def reader(path: Path) -> RrdReader:
    """The recording's reader, for its store entries (`recordings()`) and saved blueprints (`blueprints()`).

    A saved live recording has no footer on purpose (rfr_viz.recordings.live): not worth a warning here."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=NO_FOOTER)
        return RrdReader(path)


def has_footer(path: Path) -> bool:
    """Whether the file ends in Rerun's footer (a manifest of every chunk); RrdReader warns when not."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        RrdReader(path)
    return not any(NO_FOOTER in str(warning.message) for warning in caught)


def batches(path: Path, content: str) -> list[pa.RecordBatch]:
    return [chunk.to_record_batch() for chunk in reader(path).stream().filter(content=content).to_chunks()]


def rows(path: Path, entity: str, column: str) -> list[tuple[int, Any]]:
    """(frame, value) of every temporal row of `entity` holding `column`, in frame order.

    Only `frame` and `column` are converted: at rates like 6.5 fps the "time" column holds
    durations that are not whole microseconds, which Python's timedelta cannot take.
    """
    found = []
    for batch in batches(path, entity):
        if column in batch.schema.names and "frame" in batch.schema.names:
            data = batch.select(["frame", column]).to_pydict()
            found += [
                (frame, value) for frame, value in zip(data["frame"], data[column], strict=True) if value
            ]
    return sorted(found, key=lambda row: row[0])


def values(path: Path, entity: str, column: str) -> tuple[list[int], list[Any]]:
    """Frames and first values of `entity`'s temporal rows holding `column`, in frame order."""
    found = rows(path, entity, column)
    return [frame for frame, _ in found], [value[0] for _, value in found]


def columns(path: Path, entity: str) -> dict[str, list[Any]]:
    """Every column of `entity`'s chunks, concatenated (static columns hold one row)."""
    found: dict[str, list[Any]] = {}
    for batch in batches(path, entity):
        for name, column in batch.to_pydict().items():
            found.setdefault(name, []).extend(column)
    return found


def static_value(path: Path, entity: str, column: str) -> Any:
    for batch in batches(path, entity):
        if column in batch.schema.names and "frame" not in batch.schema.names:
            return batch.to_pydict()[column][0]
    raise AssertionError(f"no static {column} at {entity}")


def entity_paths(path: Path) -> set[str]:
    return {str(chunk.entity_path) for chunk in reader(path).stream().to_chunks()}


def properties(path: Path, group: str = "robofailring") -> dict[str, Any]:
    for batch in batches(path, f"/__properties/{group}"):
        return {k: v[0][0] for k, v in batch.to_pydict().items() if k != "rerun.controls.RowId"}
    raise AssertionError(f"no property group {group}")


def blueprint_names(path: Path) -> list[str]:
    """The display names of the views and containers in the recording's saved blueprint, sorted."""
    read = reader(path)
    names = []
    for store in read.blueprints():
        for chunk in read.stream(store=store).to_chunks():
            batch = chunk.to_record_batch()
            for column in batch.schema.names:
                if column.endswith("Blueprint:display_name"):
                    names += [value[0] for value in batch.column(column).to_pylist() if value]
    return sorted(names)


def every_text(path: Path) -> str:
    """Every value in the recording (its data and its blueprints) as text: for what a recording must not hold.

    Time columns are left out (see `rows`): they hold numbers, not text."""
    read = reader(path)
    texts = []
    for store in [*read.recordings(), *read.blueprints()]:
        for chunk in read.stream(store=store).to_chunks():
            batch = chunk.to_record_batch()
            for name, column in zip(batch.schema.names, batch.columns, strict=True):
                if not pa.types.is_temporal(column.type):
                    texts.append(f"{name}: {column.to_pylist()}")
    return "\n".join(texts)


def blobs(path: Path) -> list[bytes]:
    """Every image's encoded bytes in the recording (`EncodedImage:blob` of any entity, any row)."""
    read = reader(path)
    found = []
    for chunk in read.stream(store=read.recordings()[0]).to_chunks():
        batch = chunk.to_record_batch()
        for name, column in zip(batch.schema.names, batch.columns, strict=True):
            if name.endswith("EncodedImage:blob"):
                found += [bytes(cell[0]) for cell in column.to_pylist() if cell]
    return found


def psnr(decoded: np.ndarray, source: np.ndarray) -> float:
    """How near a camera frame read back (decoded from a recording's video) is to the frame logged, in dB
    (inf when equal)."""
    mse = float(np.mean((decoded.astype(np.float64) - source) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(255.0**2 / mse)
