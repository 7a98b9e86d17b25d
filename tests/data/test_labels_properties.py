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

from robofailring.data.labels import apply_labels, read_labels
from robofailring.data.model import Frame, Outcome, Trajectory
from robofailring.errors import DataError

COLUMNS = ("episode_index", "episode", "outcome", "symbol", "onset_frame")
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
            for label in labels.values():  # an onset is a frame number, and only a failure's
                assert label.onset_frame is None or (
                    type(label.onset_frame) is int and label.onset_frame >= 0
                )
                assert label.onset_frame is None or label.outcome.value == "failure"


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


ONSETS = st.one_of(
    st.integers(min_value=-3, max_value=12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(["", "2", " 4 ", "2.0", "2.5", "-1", "soon", "1e3"]),
    st.none(),
)


@given(onset=ONSETS, length=st.integers(min_value=1, max_value=8), as_json=st.booleans())
def test_an_onset_frame_is_applied_within_the_episode_or_refused_naming_file_row_and_value(
    onset: Any, length: int, as_json: bool
) -> None:
    """A labelled onset lands on the trajectory as a frame number below its length, or the labels file is
    refused with a DataError naming the file, the row and the value."""
    row = {"episode": "run_a", "outcome": "failure", "symbol": "grasp_wp2", "onset_frame": onset}
    frames = [Frame(path=Path(f"run_a/front_{i}.png")) for i in range(length)]
    trajectory = Trajectory(task="pick_cube", episode="run_a", views={"front": frames}, onset_frame=0)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / ("labels.json" if as_json else "labels.csv")
        path.write_bytes(json.dumps([row]).encode() if as_json else _csv([row]))
        try:
            (labelled,) = apply_labels([trajectory], read_labels(path), source=path)
        except DataError as error:
            assert str(path) in str(error) and "row 1" in str(error) and "onset_frame" in str(error)
        else:
            assert labelled.outcome is Outcome.FAILURE
            assert type(labelled.onset_frame) is int and 0 <= labelled.onset_frame < length
            if onset is None or onset == "":
                assert labelled.onset_frame == 0  # no labelled onset: the data's own stays
            else:
                assert labelled.onset_frame == float(str(onset).strip())
