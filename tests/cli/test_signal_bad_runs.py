"""One run's bad signal is that run's alone (issue 50): a task's signal layout is decided by all its runs, so a
NaN, an infinity, a value beyond float32, a wrong row count, 10,000 dimensions, strings or a wider state in
its *first* run (or any other) lists that run as skipped for signals with the reason (exit status 3) while
every other run keeps the signal; a wider state is never cut to fit."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli, refused
from synthetic import write_project_dataset

from robofailring import FailureMemory, load_dataset
from robofailring.memory.signals.layout import ACTION_LAGS

LENGTH = 8


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("bad-signals") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=4,
        length=LENGTH,
        signals=True,
    )


def _spoil(data: Path, case: str, *, which: int) -> tuple[Path, str]:
    """A copy of `data` whose run number `which` (in the order the task's runs are read) has a bad
    `gripper_width`; the copy and that run's episode name."""
    root = data.parent / f"{case}-{which}"
    if not root.exists():
        shutil.copytree(data, root)
    run = list(load_dataset(root))[which]
    folder = root / run.episode
    values = dict(np.load(folder / "signals.npz"))
    width = values["gripper_width"].copy()
    if case in ("nan", "inf", "huge"):
        width[3, 0] = {"nan": np.nan, "inf": np.inf, "huge": 1e300}[case]
    elif case == "rows":
        width = width[:5]  # matches no view's frame count
    elif case == "dimensions":
        width = np.zeros((LENGTH, 10_000))
    elif case == "text":
        width = np.array([["wide"]] * LENGTH)
    elif case == "wider":  # a 3-d gripper state among 1-d ones, its dimensions named
        width = np.concatenate([width, np.zeros((LENGTH, 2))], axis=1)
        manifest = json.loads((root / "manifest.json").read_text())
        record = next(r for r in manifest["episodes"] if r["episode"] == run.episode)
        record["signals"]["signals"] = {
            **record["signals"]["signals"],
            "gripper_width": {"kind": "state", "names": ["width", "left", "right"]},
        }
        (root / "manifest.json").write_text(json.dumps(manifest))
    values["gripper_width"] = width
    np.savez(folder / "signals.npz", **values)  # type: ignore[arg-type]
    return root, run.episode


REASONS = {
    "nan": "NaN, infinite or beyond",
    "inf": "NaN, infinite or beyond",
    "huge": "NaN, infinite or beyond ±3.4e+38 (the first at frame 3, dimension 0: 1e+300)",
    "rows": "5 rows, but the trajectory's views have 8 frames",
    "dimensions": "10000 dimensions per frame (a signal has 1 to 512)",
    "text": "are not numbers",
    "wider": "signal 'gripper_width' has 3 dimension(s) (width, left, right), but the task's runs have 1 (width)",
}


@pytest.mark.parametrize("which", [0, -1], ids=["first-run", "last-run"])
@pytest.mark.parametrize("case", list(REASONS))
def test_one_runs_bad_signal_skips_that_run_alone_and_says_why(
    data: Path, cache: list[str], tmp_path: Path, case: str, which: int
) -> None:
    root, spoiled = _spoil(data, case, which=which)
    memory = tmp_path / "memory"
    built = cli("build-memory", root, "--out", memory, *cache)
    assert built.exit_code == 3, built.output  # partly read, as blind frames are
    listed = [line for line in built.output.splitlines() if "signals not used" in line]
    assert len(listed) == 1 and spoiled in listed[0] and REASONS[case] in listed[0], built.output
    signals = FailureMemory.load(memory).signals
    assert signals is not None
    task = signals.task("pick_cube")
    assert task is not None
    assert task.layout.state == (("gripper_width", ("width",)),)  # never cut, never widened
    assert task.layout.action == (("action", ("x", "gripper")),)
    kept = {*task.rows["failure"].episodes.tolist(), *task.rows["success"].episodes.tolist()}
    assert kept == {run.episode for run in load_dataset(root)} - {spoiled}  # every other run keeps it
    recorded = json.loads((memory / "manifest.json").read_text())[
        "skipped_inputs"
    ]  # kept, as what is not read
    assert [s["path"] for s in recorded] == [str(root / spoiled)] and REASONS[case] in recorded[0]["reason"]


def test_a_signal_no_run_reads_well_is_left_out_and_every_run_listed(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    root = tmp_path / "data"
    shutil.copytree(data, root)
    for run in load_dataset(root):
        values = dict(np.load(root / run.episode / "signals.npz"))
        values["action"] = np.full((LENGTH, 2), np.nan)
        np.savez(root / run.episode / "signals.npz", **values)  # type: ignore[arg-type]
    memory = tmp_path / "memory"
    built = cli("build-memory", root, "--out", memory, *cache)
    assert built.exit_code == 3, built.output
    listed = [line for line in built.output.splitlines() if "signal not used" in line]
    assert len(listed) == len(list(load_dataset(root))), built.output
    assert all("signal 'action'" in line and "NaN" in line for line in listed)
    signals = FailureMemory.load(memory).signals
    assert signals is not None and signals.task("pick_cube").layout.names == ["gripper_width"]  # type: ignore[union-attr]


@pytest.mark.parametrize("weight", ["1e308", "inf", "nan", "-0.5", "101"])
def test_a_start_weight_out_of_range_is_refused_before_anything_is_read(
    data: Path, cache: list[str], tmp_path: Path, weight: str
) -> None:
    memory = tmp_path / "memory"
    refused(
        cli("build-memory", data, "--out", memory, "--signal-start-weight", weight, *cache),
        2,
        "--signal-start-weight",
        "from 0 to 100",
    )
    assert not memory.exists()


def test_the_largest_start_weight_gives_finite_vectors_that_are_scored(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    memory = tmp_path / "memory"
    # the signals named (not `auto`), so every element of the vectors is kept, the weighted start state with it
    named = ("--signals", "gripper_width,action")
    built = cli("build-memory", data, "--out", memory, "--signal-start-weight", "100", *named, *cache)
    assert built.exit_code == 0, built.output
    with np.load(memory / "signals.npz") as stored:
        assert all(np.isfinite(stored[name]).all() for name in stored.files if stored[name].dtype.kind == "f")
    signals = FailureMemory.load(memory).signals
    assert signals is not None and signals.start_weight == 100.0
    task = signals.task("pick_cube")
    assert task is not None
    state = task.widths[0]
    width = 2 * state + len(ACTION_LAGS) * task.widths[1] + 1
    assert task.vectors["success"].shape[1] == width
    found = cli(
        "detect", data, "--memory", memory, "--trajectory", "pick_cube_grasp_wp2_episode1", "--json", *cache
    )
    assert found.exit_code == 0, found.output
    scored = json.loads(found.stdout)["signals"]
    assert scored is not None and np.isfinite(scored["failure_similarity"]).all()


def test_runs_with_bad_signals_are_kept_in_the_manifest_of_a_grown_memory(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    root, spoiled = _spoil(data, "nan", which=-1)
    memory = tmp_path / "memory"
    built = cli("build-memory", root, "--out", memory, "--split", "train", *cache)
    assert built.exit_code == 0, built.output  # the spoiled run is a test run: not in this build
    grown = cli("build-memory", root, "--add-to", memory, "--split", "test", *cache)
    assert grown.exit_code == 3, grown.output
    recorded = json.loads((memory / "manifest.json").read_text())["skipped_inputs"]
    assert [s["path"] for s in recorded] == [str(root / spoiled)], recorded
    assert "signals not used" in recorded[0]["reason"] and REASONS["nan"] in recorded[0]["reason"]


def test_an_evaluation_lists_every_run_whose_signals_it_did_not_use(
    data: Path, cache: list[str], tmp_path: Path
) -> None:
    """The training memory's run, the deployment success's and the test run's bad signals: each listed in the
    evaluation's JSON and Markdown and on the terminal, with status 3 (none was, and the status was 0)."""
    root = tmp_path / "data"
    shutil.copytree(data, root)
    runs = {run.episode: run for run in load_dataset(root)}
    training, deployed, tested = (
        "pick_cube_success_episode0",  # a training success: in the memory evaluate builds
        "pick_cube_success_episode1",  # the first test success: moved by --deployment-successes 1
        "pick_cube_grasp_wp2_episode3",  # a test failure: judged by its cameras alone
    )
    assert (runs[training].split, runs[deployed].split, runs[tested].split) == ("train", "test", "test")
    for episode in (training, deployed, tested):
        values = dict(np.load(root / episode / "signals.npz"))
        values["gripper_width"][3, 0] = np.nan
        np.savez(root / episode / "signals.npz", **values)  # type: ignore[arg-type]
    out = tmp_path / "evaluation"
    evaluated = cli(
        "evaluate", root, "--out", out, "--deployment-successes", "1", "--target-fpr", "0.5", *cache
    )
    assert evaluated.exit_code == 3, evaluated.output
    listed = json.loads((out / "evaluation.json").read_text())["skipped_inputs"]
    reasons = {Path(s["path"]).name: s["reason"] for s in listed}
    assert set(reasons) == {training, deployed, tested}, listed
    assert reasons[training].startswith("signals not used") and reasons[deployed].startswith(
        "signals not used"
    )
    assert reasons[tested].startswith("signals not scored (cameras alone)")
    markdown = (out / "evaluation.md").read_text()
    assert all(f"/{episode}`" in markdown for episode in reasons)
    assert all(episode in evaluated.output for episode in reasons)
