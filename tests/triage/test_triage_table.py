"""`triage.csv`: rows in rank order, read back by the one labels parser, merged without blanking a person's work."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from synthetic import csv_rows

from robofailring.data.labels import read_labels, unlabelled_rows
from robofailring.data.model import Outcome, Trajectory
from robofailring.errors import DataError, OutputError
from robofailring.triage.scoring import EpisodeScore
from robofailring.triage.table import COLUMNS, check_table, check_unique_episodes, table_rows, write_table


def _ranked(*episodes: str) -> list[EpisodeScore]:
    return [
        EpisodeScore(
            task="pick_cube",
            episode=episode,
            mode="others",
            rule="novelty",
            threshold=0.1,
            curve=np.zeros(3, np.float32),
            peak=0.5 - rank / 10,
            frame=rank,
            view="front",
            rank_score=3.0 - rank,
            rank=rank,
            normal_episode="run_x",
            normal_frame=2,
        )
        for rank, episode in enumerate(episodes, 1)
    ]


def test_rows_in_rank_order_read_back_as_labels_once_filled(tmp_path: Path) -> None:
    path = write_table(
        tmp_path / "triage.csv",
        table_rows(_ranked("run_b", "run_a"), open_commands={"pick_cube/run_b": "robofailring open x.rrd"}),
    )
    rows = csv_rows(path)
    assert list(rows[0]) == list(COLUMNS)
    assert [(r["rank"], r["episode"], r["frame"], r["view"]) for r in rows] == [
        ("1", "run_b", "1", "front"),
        ("2", "run_a", "2", "front"),
    ]
    assert rows[0]["open"] == "robofailring open x.rrd" and rows[0]["nearest_normal"] == "run_x frame 2"
    assert {r["outcome"] + r["symbol"] + r["description"] for r in rows} == {""}
    with pytest.raises(DataError, match="no labelled row"):
        read_labels(path)
    rows[1] |= {"outcome": "failure", "symbol": "grasp_wp2", "description": "it never closed"}
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(COLUMNS))
        writer.writeheader()
        writer.writerows(rows)
    labels = read_labels(path)
    assert labels["run_a"].outcome is Outcome.FAILURE and labels["run_a"].symbol == "grasp_wp2"
    assert labels["run_a"].description == "it never closed" and labels["run_a"].task == "pick_cube"
    assert unlabelled_rows(path) is not None  # run_b: not labelled yet, reported as not applied


def test_a_second_triage_keeps_what_a_person_filled_and_re_ranks(tmp_path: Path) -> None:
    path = write_table(tmp_path / "triage.csv", table_rows(_ranked("run_a", "run_b", "run_c")))
    rows = csv_rows(path)
    rows[2] |= {"outcome": "success", "notes": "looked fine"}  # a person's own column stays too
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=[*COLUMNS, "notes"])
        writer.writeheader()
        writer.writerows(rows)
    write_table(path, table_rows(_ranked("run_c", "run_b")))  # run_a not in this triage
    again = csv_rows(path)
    assert [(r["episode"], r["rank"], r["outcome"], r["notes"]) for r in again] == [
        ("run_c", "1", "success", "looked fine"),
        ("run_b", "2", "", ""),
        ("run_a", "1", "", ""),  # another triage's row: kept, after this one's
    ]


def test_labels_from_the_labels_file_are_filled_in(tmp_path: Path) -> None:
    known = Trajectory(
        task="pick_cube", episode="run_a", views={}, outcome=Outcome.FAILURE, symbol="slip_wp3"
    )
    rows = table_rows(_ranked("run_a", "run_b"), labelled={"pick_cube/run_a": known})
    assert (rows[0]["outcome"], rows[0]["symbol"], rows[1]["outcome"]) == ("failure", "slip_wp3", "")


def test_a_file_that_is_not_a_labels_csv_is_refused_before_any_work(tmp_path: Path) -> None:
    other = tmp_path / "triage.csv"
    other.write_text("name,value\nx,1\n")
    with pytest.raises(OutputError, match="not a labels CSV"):
        check_table(other)
    assert other.read_text() == "name,value\nx,1\n"
    check_table(tmp_path / "absent.csv")  # nothing there: fine


def test_one_episode_name_in_two_tasks_is_an_error() -> None:
    runs = [Trajectory(task=task, episode="episode_0", views={}) for task in ("pick", "push")]
    with pytest.raises(DataError, match="triage one task at a time"):
        check_unique_episodes(runs)
