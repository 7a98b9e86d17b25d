"""Files a user keeps in `--out` are never replaced (issue 45, item 5): `evaluate` and `triage` write
their tables and pages only over files they wrote themselves, and refuse before any work otherwise."""

from __future__ import annotations

from pathlib import Path

import pytest
from fault_helpers import cli, refused, tree
from synthetic import write_project_dataset

USERS = {
    "report.html": "<html><title>my notes</title></html>",
    "evaluation.json": '{"mine": true}',
    "evaluation.md": "# my evaluation notes\n",
    "evaluation.rrd": "not a recording",
}


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
