"""A LeRobot dataset's metadata is input: any `meta/info.json`, `episodes.jsonl` row or episode table
value is read or refused with a DataError naming the dataset's file, never another exception."""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from lerobot_writer import write_lerobot_v3, write_lerobot_v21

from robofailring.data.layouts.lerobot import INFO, lerobot_trajectories
from robofailring.errors import DataError

JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=6,
)
INFO_KEYS = ("codebase_version", "fps", "features", "chunks_size", "data_path", "video_path")
TEMPLATES = st.sampled_from(
    ["{", "}", "{x}", "{episode_index:q}", "{video_key}", "{0}", "a/{episode_chunk.real}"]
)


@pytest.fixture(scope="module")
def datasets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("lerobot")
    small = {"lengths": (3, 2), "tasks": ("open", "close"), "cameras": ("front",), "size": 16}
    return {
        "v2.1": write_lerobot_v21(root / "v21", **small),  # type: ignore[arg-type]
        "v3.0": write_lerobot_v3(root / "v3", **small),  # type: ignore[arg-type]
    }


@pytest.fixture(scope="module")
def scratch(datasets: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Path]]:
    copies = {}
    for version, source in datasets.items():
        copies[version] = tmp_path_factory.mktemp("scratch") / source.name
        shutil.copytree(source, copies[version])
    yield copies


def _read_with(root: Path, source: Path, name: str, content: bytes) -> None:
    original = (source / name).read_bytes()
    (root / name).write_bytes(content)
    try:
        lerobot_trajectories(root)
    except DataError as error:
        assert str(root) in str(error)
    finally:
        (root / name).write_bytes(original)


@given(
    st.sampled_from(["v2.1", "v3.0"]),
    st.dictionaries(st.sampled_from(INFO_KEYS), JSON | TEMPLATES, max_size=3),
    st.lists(st.sampled_from(INFO_KEYS), max_size=2),
)
def test_any_info_json_is_read_or_refused_naming_the_dataset(
    datasets: dict[str, Path],
    scratch: dict[str, Path],
    version: str,
    changed: dict[str, Any],
    removed: list[str],
) -> None:
    info = json.loads((datasets[version] / INFO).read_text()) | changed
    for key in removed:
        info.pop(key, None)
    _read_with(scratch[version], datasets[version], INFO, json.dumps(info).encode())


@given(st.sampled_from(["v2.1", "v3.0"]), st.binary(max_size=60))
def test_any_info_bytes_are_read_or_refused(
    datasets: dict[str, Path], scratch: dict[str, Path], version: str, content: bytes
) -> None:
    _read_with(scratch[version], datasets[version], INFO, content)


@given(
    st.lists(
        st.one_of(
            st.text(max_size=20),
            JSON.map(json.dumps),
            st.fixed_dictionaries(
                {"episode_index": JSON, "length": JSON, "tasks": JSON | st.just(["open"])}
            ).map(json.dumps),
        ),
        min_size=1,
        max_size=3,
    )
)
def test_any_v21_episode_rows_are_read_or_refused(
    datasets: dict[str, Path], scratch: dict[str, Path], rows: list[str]
) -> None:
    _read_with(scratch["v2.1"], datasets["v2.1"], "meta/episodes.jsonl", "\n".join(rows).encode())


COLUMN_VALUES = st.one_of(
    st.lists(st.integers(-(2**63), 2**63 - 1) | st.none(), min_size=2, max_size=2).map(
        lambda v: pa.array(v, pa.int64())
    ),
    st.lists(st.floats() | st.none(), min_size=2, max_size=2).map(lambda v: pa.array(v, pa.float64())),
    st.lists(st.text(max_size=6) | st.none(), min_size=2, max_size=2).map(lambda v: pa.array(v, pa.string())),
)


@settings(max_examples=15)
@given(st.data())
def test_any_v3_episode_table_values_are_read_or_refused(
    datasets: dict[str, Path], scratch: dict[str, Path], data: st.DataObject
) -> None:
    name = "meta/episodes/chunk-000/file-000.parquet"
    table = pq.read_table(datasets["v3.0"] / name)
    column = data.draw(st.sampled_from(table.column_names))
    fuzzed = table.set_column(table.column_names.index(column), column, data.draw(COLUMN_VALUES))
    sink = pa.BufferOutputStream()
    pq.write_table(fuzzed, sink)
    _read_with(scratch["v3.0"], datasets["v3.0"], name, sink.getvalue().to_pybytes())
