"""Labels files are user input: any CSV or JSON file is read or refused with a DataError naming the file."""

from __future__ import annotations

import csv
import io
import json
import tempfile
from pathlib import Path
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

from robofailring.data.labels import read_labels
from robofailring.errors import DataError

COLUMNS = ("episode_index", "episode", "outcome", "symbol")
VALUES = st.one_of(
    st.sampled_from(
        ["", "0", "3", "-1", "1.5", "success", "failure", "FAILURE", "grasp_wp2", "episode", "episode3"]
    ),
    st.text(max_size=12),
    st.integers(),
    st.floats(),
    st.booleans(),
    st.none(),
)
JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=8,
)
ROWS = st.lists(st.dictionaries(st.sampled_from(COLUMNS), VALUES), max_size=4)


def _read(name: str, content: bytes) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_bytes(content)
        try:
            labels = read_labels(path)
        except DataError as error:
            assert str(path) in str(error)
        else:
            assert labels and all(label.outcome.value in ("success", "failure") for label in labels.values())


def _csv(rows: list[dict[str, Any]]) -> bytes:
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=COLUMNS)
    writer.writeheader()
    writer.writerows(rows)
    return text.getvalue().encode()


@given(ROWS)
def test_any_csv_rows_are_read_or_refused_naming_the_file(rows: list[dict[str, Any]]) -> None:
    _read("labels.csv", _csv(rows))


@given(st.one_of(ROWS, JSON))
def test_any_json_labels_are_read_or_refused_naming_the_file(value: Any) -> None:
    _read("labels.json", json.dumps(value).encode())


@given(st.binary(max_size=200), st.sampled_from(["labels.csv", "labels.json"]))
def test_any_bytes_are_read_or_refused_naming_the_file(content: bytes, name: str) -> None:
    _read(name, content)
