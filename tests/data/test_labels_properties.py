"""Labels files are user input: any CSV or JSON file is read or refused with a DataError naming the file."""

from __future__ import annotations

import csv
import io
import json
import tempfile
from pathlib import Path
from typing import Any

import pytest
from crafted import nested_json
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from robofailring.data.labels import apply_labels, merge_label_rows, read_labels
from robofailring.data.model import Frame, Outcome, Trajectory
from robofailring.errors import DataError, OutputError

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


@given(st.integers(min_value=1, max_value=200_000), st.sampled_from(["[", "{"]))
@example(100_000, "[")  # issue 45, item 6: a RecursionError, not a DataError
def test_json_labels_nested_to_any_depth_are_refused_naming_the_file(depth: int, opener: str) -> None:
    _read("labels.json", nested_json(depth, opener=opener).encode())


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


_CELL = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=6)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    existing=st.dictionaries(st.sampled_from(["e0", "e1", "e2", "e3"]), st.tuples(_CELL, _CELL), max_size=4),
    fresh=st.lists(st.sampled_from(["e1", "e2", "e4", "e5"]), unique=True, max_size=4),
)
def test_merging_labels_never_blanks_a_filled_cell_nor_drops_a_row(
    tmp_path_factory: pytest.TempPathFactory,
    existing: dict[str, tuple[str, str]],
    fresh: list[str],
) -> None:
    path = tmp_path_factory.mktemp("merge") / "labels.csv"
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "outcome", "own"])
        writer.writerows([episode, outcome, own] for episode, (outcome, own) in existing.items())
    columns = ["episode", "score", "outcome"]
    new_rows = [{"episode": episode, "score": "0.1", "outcome": ""} for episode in fresh]
    names, merged = merge_label_rows(path, new_rows, columns)
    assert names == ["episode", "score", "outcome", "own"]
    by_episode = {row["episode"]: row for row in merged}
    assert list(by_episode) == list(existing) + [e for e in fresh if e not in existing]
    for episode in existing:
        read_back = next(
            r
            for r in csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"), newline=""))
            if r["episode"] == episode
        )
        assert by_episode[episode].get("own", "") == read_back["own"]
        if read_back["outcome"].strip():
            assert by_episode[episode]["outcome"] == read_back["outcome"]
    for episode in fresh:
        assert by_episode[episode]["score"] == "0.1"


def test_merging_refuses_what_is_not_a_labels_csv(tmp_path: Path) -> None:
    for name, content in (
        ("other.csv", b"run,accuracy\n1,0.9\n"),
        ("labels.json", b"[]"),
        ("x.csv", b"\xff\xfe"),
    ):
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(OutputError, match="not a labels CSV"):
            merge_label_rows(path, [], ["episode", "outcome"])
    assert merge_label_rows(tmp_path / "absent.csv", [{"episode": "a"}], ["episode"]) == (
        ["episode"],
        [{"episode": "a"}],
    )


def test_labels_columns_quotes_and_onsets_are_read_exactly_or_refused(tmp_path: Path) -> None:
    """Issue 35, item 9: an unterminated quote, a column named twice (`outcome` and `Outcome`) and an
    onset that is not written as an integer are errors naming the file; a header in another case reads."""
    path = tmp_path / "labels.csv"
    path.write_text('episode,outcome,task\nrun_1,failure,"pick cube\nrun_2,success,pick_cube\n')
    with pytest.raises(DataError, match=r"labels\.csv line \d+: not a readable CSV"):
        read_labels(path)
    path.write_text("episode,outcome,Outcome\nrun_1,failure,success\n")
    with pytest.raises(DataError, match="columns 'outcome' and 'Outcome' both name 'outcome'"):
        read_labels(path)
    path.write_text("episode,outcome,outcome\nrun_1,failure,success\n")
    with pytest.raises(DataError, match="both name 'outcome'"):
        read_labels(path)
    path.write_text(" Episode ,OUTCOME,Onset_Frame\nrun_1,failure,3\n")
    assert read_labels(path)["run_1"].onset_frame == 3
    for onset in ("3.0", "1e2", "0x10", "3 frames", "½"):
        path.write_text(f"episode,outcome,onset_frame\nrun_1,failure,{onset}\n")
        with pytest.raises(DataError, match="is not an integer frame number"):
            read_labels(path)
    as_json = tmp_path / "labels.json"
    for onset, expected in ((3.0, None), (100, 100), ("7", 7)):
        as_json.write_text(json.dumps([{"episode": "run_1", "outcome": "failure", "onset_frame": onset}]))
        if expected is None:
            with pytest.raises(DataError, match="is not an integer frame number"):
                read_labels(as_json)
        else:
            assert read_labels(as_json)["run_1"].onset_frame == expected
