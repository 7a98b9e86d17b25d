"""Label what the detector flags and grow the memory: review --write-labels, build-memory --add-to."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

from fault_helpers import DIE_ON_REPLACE, cli, hidden, killed, refused, tree
from synthetic import csv_rows, write_aha_dataset, write_project_dataset

from robofailring import FailureMemory

MISS_TEXT = "the cube slid out of the gripper while lifting"


def _evaluated(tmp_path: Path, cache: list[str]) -> tuple[Path, Path, dict[str, str]]:
    """A tiny project dataset, its evaluation, and that evaluation's JSON edited to one false alarm and one miss."""
    data = write_project_dataset(
        tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2", "slip_wp3"), episodes=2, length=5
    )
    evaluated = cli("evaluate", data, "--out", tmp_path / "eval", "--target-fpr", "0.5", *cache)
    assert evaluated.exit_code == 0, evaluated.output
    json_path = tmp_path / "eval" / "evaluation.json"
    evaluation = json.loads(json_path.read_text())
    keys = {"alarm": "pick_cube/pick_cube_success_episode1", "miss": "pick_cube/pick_cube_slip_wp3_episode1"}
    evaluation["rules"]["paper"] |= {"false_alarms": [keys["alarm"]], "misses": [keys["miss"]]}
    json_path.write_text(json.dumps(evaluation))
    return data, json_path, keys


def test_label_the_flagged_runs_grow_the_memory_and_detect_finds_the_new_failure(
    cache: list[str], tmp_path: Path
) -> None:
    data, json_path, keys = _evaluated(tmp_path, cache)
    memory = tmp_path / "eval" / "memory"
    before = FailureMemory.load(memory)
    assert {e.episode for e in before.entries}.isdisjoint({k.split("/")[1] for k in keys.values()})

    labels = tmp_path / "labels.csv"
    written = cli("review", json_path, "--data", data, "--score", "paper", "--write-labels", labels, *cache)
    assert written.exit_code == 0, written.output
    rows = csv_rows(labels)
    assert [(r["episode"], r["review"], r["detected"]) for r in rows] == [
        ("pick_cube_success_episode1", "false alarm", "failure"),
        ("pick_cube_slip_wp3_episode1", "miss", "success"),
    ]
    entries = {e.symbol for e in before.entries}
    assert all(r["suggested_symbol"] in entries and r["rule"] == "paper" for r in rows)
    assert all(r["outcome"] == r["symbol"] == r["description"] == "" for r in rows)
    assert all(-1 <= float(r["score"]) <= 1 and 0 <= int(r["frame"]) < 5 for r in rows)

    # a person fills the two rows: the false alarm was a success, the miss a failure in their own words
    rows[0]["outcome"] = "success"
    rows[1] |= {"outcome": "failure", "description": MISS_TEXT}
    with labels.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)

    grown = cli("build-memory", data, "--labels", labels, "--add-to", memory, *cache)
    assert grown.exit_code == 0, grown.output
    after = FailureMemory.load(memory)
    added = after.entries[len(before.entries) :]
    # evaluate built a dense memory, so the new failure is added dense: frames 1-4 of 5 of each of its 3 views
    assert after.manifest.failure_mode == before.manifest.failure_mode == "dense"
    assert len(after) == len(before) + 12 and after.vectors[: len(before)].tolist() == before.vectors.tolist()
    assert {(e.episode, e.symbol, e.description) for e in added} == {
        ("pick_cube_slip_wp3_episode1", "failure", MISS_TEXT)
    }
    assert sorted((e.view, e.frame, e.length) for e in added) == [
        (view, frame, 5) for view in ("front", "overhead", "wrist") for frame in (1, 2, 3, 4)
    ]
    assert after.successes is not None and before.successes is not None
    assert (
        len(after.successes.runs) == len(before.successes.runs) + 6
    )  # 3 views of the success, 3 failure starts
    assert after.data_root == before.data_root and after.manifest.calibration is None
    assert after.manifest.failures == (before.manifest.failures or 0) + 1

    detected = cli(
        "detect", data, "--memory", memory, "--trajectory", keys["miss"], "--delta", "0.5", "--json", *cache
    )
    assert detected.exit_code == 0, detected.output
    report = json.loads(detected.stdout)["report"]
    nearest = report["neighbors"][0]
    assert (
        nearest["symbol"] == "failure" and nearest["description"] == MISS_TEXT
    )  # only the new entry says it

    again = cli("build-memory", data, "--labels", labels, "--add-to", memory, *cache)
    refused(again, 2, "already holds episode", "pick_cube_slip_wp3_episode1")
    assert FailureMemory.load(memory).vectors.tolist() == after.vectors.tolist()


def test_add_to_keeps_the_calibration_note_and_an_interrupted_add_leaves_the_old_memory(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    manifest = json.loads((memory / "manifest.json").read_text())
    manifest["calibration"] = {"encoder": manifest["encoder"], "delta": 0.9}
    (memory / "manifest.json").write_text(json.dumps(manifest))
    old = tree(memory)
    new = write_aha_dataset(
        tmp_path / "new", tasks=("pick_cube",), symbols=("slip_wp3",), episodes=1, length=3
    )
    killed(DIE_ON_REPLACE, memory, "build-memory", new, "--add-to", memory, *cache)
    detected = cli("detect", new / "pick_cube_slip_wp3_episode0", "--memory", memory, *cache)
    assert detected.exit_code == 0, detected.output  # the next run restores the old memory
    assert tree(memory) == old and hidden(tmp_path) == []

    grown = cli("build-memory", new, "--add-to", memory, *cache)
    assert grown.exit_code == 0, grown.output
    assert "had a calibrated δ = 0.900000; the new one is uncalibrated" in grown.output
    assert "calibration" not in json.loads((memory / "manifest.json").read_text())


def test_bad_vocabulary_labels_and_add_to_targets_are_named_errors(
    data: Path, memory: Path, cache: list[str], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    duplicate = tmp_path / "words.yaml"
    duplicate.write_text("symbols:\n  knocked_cup: the cup knocked over\n  knocked_cup: again\n")
    refused(
        cli("build-memory", data, "--out", out, "--vocabulary", duplicate, *cache), 2, "words.yaml", "twice"
    )
    empty = tmp_path / "words.json"
    empty.write_text(json.dumps({"symbols": {"knocked_cup": "  "}}))
    refused(cli("build-memory", data, "--out", out, "--vocabulary", empty, *cache), 2, "words.json", "empty")
    labels = tmp_path / "labels.csv"
    labels.write_text("episode,outcome,symbol\npick_cube_grasp_wp2_episode0,failure,knocked_cup\n")
    refused(
        cli("build-memory", data, "--out", out, "--labels", labels, *cache),
        2,
        "labels.csv row 1",
        "unknown failure token 'knocked'",
        "--vocabulary",
    )
    assert not out.exists()

    old = tree(memory)
    other = tmp_path / "other"
    shutil.copytree(memory, other)
    manifest = json.loads((other / "manifest.json").read_text())
    (other / "manifest.json").write_text(json.dumps(manifest | {"encoder": "open_clip:ViT-B-32:openai"}))
    new = write_aha_dataset(
        tmp_path / "new", tasks=("pick_cube",), symbols=("slip_wp3",), episodes=1, length=3
    )
    before_other = tree(other)
    refused(cli("build-memory", new, "--add-to", other, *cache), 2, "built with encoder", "--encoder")
    assert tree(other) == before_other and hidden(tmp_path) == []
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "a.txt").write_text("mine")
    refused(cli("build-memory", new, "--add-to", folder, *cache), 2, "is not a failure memory")
    refused(cli("build-memory", data, "--add-to", memory, *cache), 2, "already holds episode")
    assert tree(memory) == old and tree(folder) == {"a.txt": b"mine"}


def test_review_merges_into_a_filled_labels_file_and_refuses_any_other_file(
    cache: list[str], tmp_path: Path
) -> None:
    """Writing labels again keeps what a person filled in, other episodes' rows and their own columns
    (issue 35, item 3); a CSV that is not a labels file, a memory's manifest or a JSON file is refused
    and left as it was."""
    data, json_path, _ = _evaluated(tmp_path, cache)
    labels = tmp_path / "labels.csv"
    assert (
        cli(
            "review", json_path, "--data", data, "--score", "paper", "--write-labels", labels, *cache
        ).exit_code
        == 0
    )
    rows = csv_rows(labels)
    rows[1] |= {"outcome": "failure", "description": MISS_TEXT, "score": "0.5"}
    for row in rows:
        row["note"] = "seen by Ana" if row is rows[1] else ""
    rows.append({name: "" for name in rows[0]} | {"episode": "someone_elses_run", "outcome": "success"})
    with labels.open("w", newline="", encoding="utf-8-sig") as handle:  # as Excel saves "CSV UTF-8"
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)

    again = cli("review", json_path, "--data", data, "--score", "paper", "--write-labels", labels, *cache)
    assert again.exit_code == 0, again.output
    assert f"wrote {labels}: 1 of its 3 row(s) to label" in again.output  # only the row still empty
    merged = {row["episode"]: row for row in csv_rows(labels)}
    assert list(merged) == ["pick_cube_success_episode1", "pick_cube_slip_wp3_episode1", "someone_elses_run"]
    miss = merged["pick_cube_slip_wp3_episode1"]
    assert (miss["outcome"], miss["description"], miss["note"]) == ("failure", MISS_TEXT, "seen by Ana")
    assert (
        miss["score"] != "0.5" and miss["review"] == "miss"
    )  # the detector's columns are its own, refreshed
    assert merged["someone_elses_run"]["outcome"] == "success"
    assert merged["pick_cube_success_episode1"]["outcome"] == ""
    with labels.open("w", newline="", encoding="utf-8") as handle:  # the last row filled in too
        writer = csv.DictWriter(handle, fieldnames=list(merged["someone_elses_run"]))
        writer.writeheader()
        writer.writerows(row | {"outcome": row["outcome"] or "success"} for row in merged.values())
    done = cli("review", json_path, "--data", data, "--score", "paper", "--write-labels", labels, *cache)
    assert done.exit_code == 0, done.output
    assert f"wrote {labels}: all 3 row(s) labelled, then: robofailring build-memory" in done.output

    other = tmp_path / "results.csv"
    other.write_text("run,accuracy\n1,0.9\n")
    manifest = tmp_path / "eval" / "memory" / "manifest.json"
    for target, why in ((other, "not a labels CSV"), (manifest, "lies inside the input")):
        before = target.read_bytes()
        result = cli(
            "review", json_path, "--data", data, "--score", "paper", "--write-labels", target, *cache
        )
        refused(result, 2, str(target), why)
        assert target.read_bytes() == before
