"""Files a user keeps in `--out` are never replaced (issue 45, item 5; issue 50, data loss): `evaluate`,
`triage` and `demo` write their tables, pages and recordings only over files they wrote themselves (a
JSON of the evaluation's `format`, a recording under the project's application id), and refuse before
any work otherwise; `evaluate --name` names files inside `--out`, never a path out of it."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from fault_helpers import cli, refused, tree
from synthetic import write_project_dataset

from robofailring.outputs import EVALUATION_FORMAT

USERS = {
    "report.html": "<html><title>my notes</title></html>",
    "evaluation.json": '{"mine": true}',
    "evaluation.md": "# my evaluation notes\n",
    "evaluation.rrd": "not a recording",
}
# a JSON of the user's that has an evaluation's first two keys, and nothing else of one
USERS_EVALUATION_LIKE = '{"name": "lab notes", "encoder": "my own CNN", "runs": [1, 2]}'


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("own") / "project",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=2,
        length=3,
    )


@pytest.mark.parametrize("name", sorted(USERS))
def test_evaluate_refuses_to_replace_a_users_file(
    project: Path, cache: list[str], tmp_path: Path, name: str
) -> None:
    out = tmp_path / "eval"
    out.mkdir()
    (out / name).write_text(USERS[name])
    refused(cli("evaluate", project, "--out", out, "--target-fpr", "0.5", *cache), 2, str(out / name))
    assert tree(out) == {name: USERS[name].encode()}  # nothing replaced, nothing written beside it


def test_evaluate_runs_again_over_its_own_outputs(project: Path, cache: list[str], tmp_path: Path) -> None:
    out = tmp_path / "eval"
    first = cli("evaluate", project, "--out", out, "--target-fpr", "0.5", *cache)
    assert first.exit_code == 0, first.output
    written = {name: (out / name).read_bytes() for name in USERS}
    again = cli("evaluate", project, "--out", out, "--target-fpr", "0.5", *cache)
    assert again.exit_code == 0, again.output
    assert all((out / name).is_file() for name in written)


def test_triage_refuses_to_replace_a_users_page(project: Path, cache: list[str], tmp_path: Path) -> None:
    out = tmp_path / "triage"
    out.mkdir()
    (out / "triage.html").write_text("<html><title>my ranking</title></html>")
    refused(cli("triage", project, "--out", out, "--replays", "0", *cache), 2, str(out / "triage.html"))
    assert tree(out) == {"triage.html": b"<html><title>my ranking</title></html>"}


DEMO_OUTPUTS = (
    "report.html",
    "in-distribution.json",
    "in-distribution.md",
    "out-of-distribution.json",
    "out-of-distribution.md",
)


@pytest.mark.parametrize("name", DEMO_OUTPUTS)
def test_demo_refuses_to_replace_a_users_file(tmp_path: Path, name: str) -> None:
    """Before any simulation: the data folder given is a file, so a demo that went on would stop at its first
    step with another error instead of simulating for minutes."""
    out = tmp_path / "demo"
    out.mkdir()
    (out / name).write_text("my own notes")
    not_a_folder = tmp_path / "data"
    not_a_folder.write_text("")
    refused(cli("demo", "--out", out, "--data-dir", not_a_folder), 2, str(out / name))
    assert tree(out) == {name: b"my own notes"}


@pytest.fixture(scope="module")
def lookalikes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """A user's files that share something with the evaluation's own (issue 50, data loss): a JSON with
    `name` and `encoder` keys, and a real Rerun recording of their own tools (another application id)."""
    import rerun as rr

    path = tmp_path_factory.mktemp("users") / "mine.rrd"
    with rr.RecordingStream("my_robot_lab", recording_id="lab-session") as rec:
        rec.save(path)
        rec.log("arm/torque", rr.Scalars(1.5))
    return {"evaluation.json": USERS_EVALUATION_LIKE.encode(), "evaluation.rrd": path.read_bytes()}


@pytest.mark.parametrize("name", ["evaluation.json", "evaluation.rrd"])
def test_evaluate_refuses_to_replace_a_users_file_that_looks_like_its_own(
    project: Path, cache: list[str], tmp_path: Path, lookalikes: dict[str, bytes], name: str
) -> None:
    out = tmp_path / "eval"
    out.mkdir()
    (out / name).write_bytes(lookalikes[name])
    refused(cli("evaluate", project, "--out", out, "--target-fpr", "0.5", *cache), 2, str(out / name))
    assert tree(out) == {name: lookalikes[name]}


def test_evaluate_replaces_its_json_from_before_the_format_was_written(
    project: Path, cache: list[str], tmp_path: Path
) -> None:
    out = tmp_path / "eval"
    assert cli("evaluate", project, "--out", out, "--target-fpr", "0.5", *cache).exit_code == 0
    written = json.loads((out / "evaluation.json").read_text())
    assert written["format"] == EVALUATION_FORMAT
    earlier = {key: value for key, value in written.items() if key != "format"}  # as versions before wrote it
    (out / "evaluation.json").write_text(json.dumps(earlier))
    again = cli("evaluate", project, "--out", out, "--target-fpr", "0.5", *cache)
    assert again.exit_code == 0, again.output
    assert json.loads((out / "evaluation.json").read_text())["format"] == EVALUATION_FORMAT


def _an_episode(project: Path) -> str:
    return next(
        str(folder.relative_to(project.parent)) for folder in sorted(project.rglob("*")) if folder.is_dir()
    )


@pytest.mark.parametrize(
    "name",
    # M3: a newline or a control character made files of such names; 300 characters failed only after
    # the whole evaluation ("File name too long")
    ["../notes", "", ".hidden", "runs/first", "EPISODE/x", "two\nlines", "bell\x07", "x" * 300],
)
def test_evaluate_refuses_a_name_that_is_not_a_plain_file_name(
    project: Path, cache: list[str], tmp_path: Path, name: str
) -> None:
    """`--name ../notes` with an --out not made yet once replaced the user's notes.md beside it,
    `../<dataset>/<episode>/x` wrote into the input and `""` wrote dotfiles."""
    out = tmp_path / "eval"
    name = name.replace("EPISODE", os.path.relpath(project / _an_episode(project), out))
    (tmp_path / "notes.md").write_text("my notes\n")
    before = tree(project)
    refused(
        cli("evaluate", project, "--out", out, "--name", name, "--target-fpr", "0.5", *cache),
        2,
        "is 300 bytes long" if name == "x" * 300 else repr(name),
    )
    assert not out.exists()
    assert tree(tmp_path) == {"notes.md": b"my notes\n"}
    assert tree(project) == before
