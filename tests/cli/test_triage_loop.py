"""The triage loop end to end on the command line: triage unlabelled runs, fill the top rows, build a
memory from the partly labelled triage.csv, triage again (the ranking improves), and evaluate with it."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from synthetic import csv_rows, write_unlabelled_runs
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring.triage import ranking_quality

runner = CliRunner()


def _unlabelled_auc(rows: list[dict[str, str]], truth: dict[str, str]) -> float:
    return ranking_quality([truth[r["episode"]] != "success" for r in rows if not r["outcome"]]).auc


@pytest.mark.slow
def test_fill_the_top_rows_grow_a_memory_and_the_ranking_improves(tmp_path: Path) -> None:
    # two failures of one kind look alike: against the other runs, each hides behind the other
    data, truth = write_unlabelled_runs(
        tmp_path / "runs", failures=("grasp_wp2", "grasp_wp2", "rotation_x_wp1")
    )
    out, cache = tmp_path / "out", ["--cache-dir", str(tmp_path / "cache")]
    common = ["--task", "pick_cube", *cache]
    first = runner.invoke(app, ["triage", str(data), "--out", str(out), "--replays", "0", *common])
    assert first.exit_code == 0, first.output
    assert "assumes most runs of the task succeeded" in first.output
    rows = csv_rows(out / "triage.csv")
    before = _unlabelled_auc(rows[10:], truth)
    for row in rows[:10]:  # a person labels the top of the ranking
        kind = truth[row["episode"]]
        row |= {
            "outcome": "success" if kind == "success" else "failure",
            "symbol": "" if kind == "success" else kind,
        }
    with (out / "triage.csv").open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)

    built = runner.invoke(
        app,
        [
            "build-memory",
            str(data),
            "--labels",
            str(out / "triage.csv"),
            "--out",
            str(tmp_path / "memory"),
            *common,
        ],
    )
    assert built.exit_code == 3, built.output  # the rows not labelled yet are listed as not applied
    assert "6 row(s) with an empty outcome" in built.output

    second = runner.invoke(
        app,
        [
            "triage",
            str(data),
            "--out",
            str(out),
            "--memory",
            str(tmp_path / "memory"),
            "--replays",
            "0",
            *common,
        ],
    )
    # the one labelled failure is the memory's only one: left out, contrast has nothing to judge it by
    assert second.exit_code == 3, second.output
    assert "the contrast rule compares with" in second.output
    again = csv_rows(out / "triage.csv")
    assert sum(bool(r["outcome"]) for r in again) == 10  # nothing a person filled in was blanked
    after = _unlabelled_auc(again, truth)
    assert after > before and after == 1.0

    evaluated = runner.invoke(
        app,
        [
            "evaluate",
            str(data),
            "--labels",
            str(out / "triage.csv"),
            "--out",
            str(tmp_path / "eval"),
            *common,
        ],
    )
    assert evaluated.exit_code == 3, evaluated.output  # evaluated; the unlabelled rows listed as not applied
    assert (tmp_path / "eval" / "evaluation.json").is_file()


def test_labels_of_only_episode_and_task_triage_unlabelled_runs_of_several_tasks(tmp_path: Path) -> None:
    """Issue 50: a labels file of `episode,task` columns alone (rollouts of several tasks nobody labelled)
    gives each run its task and leaves it unlabelled: triage ranks each task's runs on its own scale,
    instead of refusing the file for holding "no labelled row"."""
    data, truth = write_unlabelled_runs(tmp_path / "runs", successes=5, length=4, task="pick_cube")
    pushes, push_truth = write_unlabelled_runs(tmp_path / "push", successes=5, length=4, task="push_cube")
    tasks = dict.fromkeys(truth, "pick_cube")
    for folder in sorted(pushes.iterdir()):
        folder.rename(data / f"push_{folder.name}")
        tasks[f"push_{folder.name}"] = "push_cube"
        truth[f"push_{folder.name}"] = push_truth[folder.name]
    labels = tmp_path / "tasks.csv"
    labels.write_text("episode,task\n" + "".join(f"{episode},{task}\n" for episode, task in tasks.items()))
    out = tmp_path / "out"
    cache = ["--cache-dir", str(tmp_path / "cache")]
    found = runner.invoke(
        app, ["triage", str(data), "--labels", str(labels), "--out", str(out), "--replays", "0", *cache]
    )
    assert found.exit_code == 0, found.output  # nothing listed as not applied: every row was
    rows = csv_rows(out / "triage.csv")
    assert {row["episode"]: row["task"] for row in rows} == tasks
    assert all(row["outcome"] == "" for row in rows)  # still unlabelled: the file said their task alone
    for task in ("pick_cube", "push_cube"):
        ranked = [truth[row["episode"]] != "success" for row in rows if row["task"] == task]
        assert ranking_quality(ranked).auc == 1.0
