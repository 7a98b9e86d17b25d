"""Bad outputs and faults, end to end through the CLI (issue 13): nothing lost, one sentence, a meaningful exit status.

Each case was reproduced against the code before its fix; real files, real processes where a
process has to die or hold a lock. Bad inputs and the embedding cache: test_faults_inputs.py.
"""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from fault_helpers import (
    DIE_ON_REPLACE,
    DIE_WHILE_WRITING,
    SIGINT_WHILE_LOADING,
    SIGINT_WHILE_WRITING,
    SIGTERM_WHILE_WRITING,
    cli,
    hidden,
    interrupted,
    killed,
    refused,
    tree,
)
from synthetic import write_aha_dataset, write_episode, write_project_dataset

from rfr_viz.viewer.rrd import recording_properties

# ---------------------------------------------------------------- data loss


def test_build_memory_never_replaces_a_folder_of_other_files_a_file_or_the_current_folder(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fresh_cache = tmp_path / "cache"
    precious = tmp_path / "notes"
    precious.mkdir()
    (precious / "thesis.txt").write_text("keep me")
    refused(
        cli("build-memory", data, "--out", precious, "--cache-dir", fresh_cache),
        2,
        "not a failure memory",
        "thesis.txt",
    )
    assert (precious / "thesis.txt").read_text() == "keep me"
    a_file = tmp_path / "memory.txt"
    a_file.write_text("mine")
    refused(cli("build-memory", data, "--out", a_file, "--cache-dir", fresh_cache), 2, "is a file")
    assert a_file.read_text() == "mine"
    work = tmp_path / "work"
    work.mkdir()
    (work / "todo.md").write_text("mine")
    monkeypatch.chdir(work)
    refused(cli("build-memory", data, "--out", ".", "--cache-dir", fresh_cache), 2, "current folder")
    assert (work / "todo.md").read_text() == "mine"
    assert hidden(tmp_path) == [] and hidden(work) == []
    assert not fresh_cache.exists()  # refused before the encoder (and its cache) was even opened


def test_build_memory_never_writes_over_into_or_around_its_dataset(tmp_path: Path) -> None:
    root = tmp_path / "datasets"
    data = write_aha_dataset(root / "aha", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=1, length=3)
    before = tree(root)
    cache = ["--cache-dir", str(tmp_path / "cache")]
    refused(cli("build-memory", data, "--out", data, *cache), 2, "is the input")
    refused(cli("build-memory", data, "--out", root, *cache), 2, "holds the input")
    refused(cli("build-memory", data, "--out", data / "memory", *cache), 2, "lies inside the input")
    assert tree(root) == before


def test_an_empty_memory_is_an_error_and_replaces_nothing(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    good = tree(memory)
    project = write_project_dataset(
        tmp_path / "project", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=3
    )
    refused(
        cli("build-memory", project, "--out", memory, "--split", "tset", *cache),
        2,
        "no trajectory of split 'tset'",
        "its splits are: test, train",
    )
    successes = tmp_path / "successes"
    for episode in range(2):
        write_episode(
            successes / f"pick_cube_success_episode{episode}", "pick_cube", None, length=3, layout="aha"
        )
    refused(  # success runs alone build a memory (novelty rule), but not without them
        cli("build-memory", successes, "--out", memory, "--no-successes", *cache),
        2,
        "holds no failure trajectory",
        "--no-successes leaves out its success runs",
    )
    assert tree(memory) == good and hidden(tmp_path) == []


def test_rebuilding_says_the_calibrated_delta_is_dropped(cache: list[str], tmp_path: Path) -> None:
    project = write_project_dataset(
        tmp_path / "project", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=3
    )
    memory = tmp_path / "memory"
    assert cli("build-memory", project, "--out", memory, "--split", "train", *cache).exit_code == 0
    calibrated = cli("calibrate", project, "--memory", memory, "--target-fpr", "0.5", *cache)
    assert calibrated.exit_code == 0, calibrated.output
    delta = json.loads((memory / "manifest.json").read_text())["calibration"]["rules"]["paper"]["threshold"]
    rebuilt = cli("build-memory", project, "--out", memory, "--split", "train", *cache)
    assert rebuilt.exit_code == 0, rebuilt.output
    assert f"calibrated δ = {delta:.6f}" in rebuilt.stderr and "robofailring calibrate" in rebuilt.stderr
    assert "calibration" not in json.loads((memory / "manifest.json").read_text())


def test_recording_names_never_collide(cache: list[str], tmp_path: Path) -> None:
    tasks = ("拾取_方块", "放置_方块", "pick cube", "pick_cube")
    data = write_aha_dataset(tmp_path / "data", tasks=tasks, symbols=("grasp_wp2",), episodes=1, length=3)
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, *cache).exit_code == 0
    out = tmp_path / "rec"
    result = cli("replay", data, "--memory", memory, "--out", out, *cache)
    assert result.exit_code == 0, result.output
    written = sorted(out.glob("*.rrd"))
    assert "4 recording(s)" in result.output and len(written) == 4
    assert sorted(recording_properties(path)["task"] for path in written) == sorted(tasks)


def test_build_memory_exits_3_when_views_were_skipped(data: Path, cache: list[str], tmp_path: Path) -> None:
    episode = write_episode(
        tmp_path / "data" / "pick_cube_grasp_wp2_episode0", "pick_cube", "grasp_wp2", length=3, layout="aha"
    )
    write_episode(episode, "pick_cube", "grasp_wp2", length=1, views=("side",), layout="aha")
    result = cli("build-memory", tmp_path / "data", "--out", tmp_path / "memory", *cache)
    assert result.exit_code == 3, result.output
    assert (
        "6 entries" in result.output  # dense: frames 1 and 2 of each of the 3 views with 3 frames
        and "skipped pick_cube/pick_cube_grasp_wp2_episode0 view side" in result.output
    )


# ---------------------------------------------------------------- a replace killed half-way


def test_a_replace_killed_between_its_renames_leaves_the_old_memory_recoverable(
    memory: Path, data: Path, cache: list[str], tmp_path: Path
) -> None:
    old_tasks = json.loads((memory / "manifest.json").read_text())["tasks"]
    one_task = write_aha_dataset(
        tmp_path / "one", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=1, length=3
    )
    killed(DIE_ON_REPLACE, memory, "build-memory", one_task, "--out", memory, *cache)
    # what SIGKILL leaves: the old memory moved aside, the new one not yet in place, the lock file
    assert not memory.exists() and sorted(name.rsplit(".", 1)[1] for name in hidden(tmp_path)) == [
        "lock",
        "old",
        "tmp",
    ]
    episode = data / "pick_cube_grasp_wp2_episode0"
    detected = cli("detect", episode, "--memory", memory, *cache)  # the next run restores it
    assert detected.exit_code == 0, detected.output
    assert json.loads((memory / "manifest.json").read_text())["tasks"] == old_tasks and hidden(tmp_path) == []

    killed(DIE_WHILE_WRITING, memory, "build-memory", one_task, "--out", memory, *cache)
    assert sorted(name.rsplit(".", 1)[1] for name in hidden(tmp_path)) == ["lock", "tmp"]
    assert json.loads((memory / "manifest.json").read_text())["tasks"] == old_tasks
    rebuilt = cli("build-memory", one_task, "--out", memory, *cache)
    assert rebuilt.exit_code == 0 and hidden(tmp_path) == []  # the killed build's leftover is gone
    assert json.loads((memory / "manifest.json").read_text())["tasks"] == {
        "pick_cube": 6
    }  # 3 views × 2 frames


def test_a_failed_replace_puts_the_old_memory_back(
    memory: Path, data: Path, cache: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    good = tree(memory)
    real = os.replace
    failed: list[str] = []

    def disk_full_on_the_final_rename(src: object, dst: object) -> None:
        if Path(str(dst)) == memory and not failed:  # the new memory's move; putting the old back works
            failed.append(str(src))
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))
        real(src, dst)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "replace", disk_full_on_the_final_rename)
    refused(cli("build-memory", data, "--out", memory, *cache), 1, "no space left", str(memory))
    monkeypatch.undo()
    assert failed and tree(memory) == good and hidden(tmp_path) == []


# ---------------------------------------------------------------- one sentence, not a traceback


def test_a_full_disk_while_writing_is_one_sentence(
    memory: Path, data: Path, cache: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import faiss

    good = tree(memory)

    def full(index: object, path: str) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), path)

    monkeypatch.setattr(faiss, "write_index", full)
    refused(cli("build-memory", data, "--out", memory, *cache), 1, "no space left on the device")
    assert tree(memory) == good and hidden(tmp_path) == []


def test_an_unwritable_output_is_refused_before_any_encoding(data: Path, tmp_path: Path) -> None:
    if os.geteuid() == 0:  # root writes anywhere it has a file system; /sys refuses even root
        locked = Path("/sys/robofailring-test")
    else:
        locked = tmp_path / "locked"
        locked.mkdir()
        locked.chmod(0o555)
    fresh_cache = tmp_path / "cache"
    refused(
        cli("build-memory", data, "--out", locked / "memory", "--cache-dir", fresh_cache),
        1,
        "cannot write",
        str(locked),
    )
    assert not fresh_cache.exists()


def test_two_builds_to_one_out(memory: Path, data: Path, cache: list[str]) -> None:
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from robofailring.atomic import output_lock\n"
            "with output_lock(sys.argv[1]):\n    print('held', flush=True); sys.stdin.read()",
            str(memory),
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        refused(cli("build-memory", data, "--out", memory, *cache), 1, "another robofailring process")
    finally:
        holder.kill()
        holder.wait()
    assert cli("build-memory", data, "--out", memory, *cache).exit_code == 0  # a dead holder locks nothing


def test_replay_outputs_are_checked(memory: Path, data: Path, cache: list[str], tmp_path: Path) -> None:
    a_file = tmp_path / "notes.txt"
    a_file.write_text("mine")
    episode = data / "pick_cube_grasp_wp2_episode0"
    refused(cli("replay", episode, "--memory", memory, "--out", a_file / "rec", *cache), 2, "is a file")
    refused(cli("replay", episode, "--memory", memory, "--out", a_file, *cache), 2, "is a file")
    refused(cli("replay", data, "--memory", memory, "--out", data / "rec", *cache), 2, "inside the input")
    refused(cli("replay", episode, "--memory", memory, "--out", memory, *cache), 2, "is the input")
    for fps in ("nan", "-1", "0"):
        refused(
            cli("replay", episode, "--memory", memory, "--out", tmp_path / "rec", "--fps", fps, *cache),
            2,
            fps,
        )
    assert a_file.read_text() == "mine" and not (tmp_path / "rec").exists()


def test_replay_exits_3_when_trajectories_were_skipped_and_cleans_killed_writes(
    memory: Path, cache: list[str], tmp_path: Path
) -> None:
    mixed = write_aha_dataset(
        tmp_path / "mixed", tasks=("pick_cube", "stack_cube"), symbols=("grasp_wp2",), episodes=1, length=3
    )
    out = tmp_path / "rec"
    out.mkdir()
    leftover = out / ".pick_cube__x.rrd.rfr-abcd1234.tmp.rrd"  # what a replay killed mid-write leaves
    leftover.write_bytes(b"RRF2 half")
    result = cli("replay", mixed, "--memory", memory, "--out", out, *cache)
    assert result.exit_code == 3, result.output
    assert "skipped stack_cube/stack_cube_grasp_wp2_episode0" in result.output
    assert "1 recording(s)" in result.output and "1 trajectories skipped" in result.output
    assert [p.name for p in out.iterdir()] == ["pick_cube__pick_cube_grasp_wp2_episode0.rrd"]


def test_evaluate_exits_3_when_test_trajectories_were_skipped(cache: list[str], tmp_path: Path) -> None:
    project = write_project_dataset(
        tmp_path / "project", tasks=("pick_cube", "push_cube"), symbols=("grasp_wp2",), episodes=2, length=3
    )
    manifest = json.loads((project / "manifest.json").read_text())
    for record in manifest["episodes"]:
        if record["task"] == "push_cube":
            record["split"] = "test"  # no push_cube failure reaches the memory
    (project / "manifest.json").write_text(json.dumps(manifest))
    result = cli("evaluate", project, "--out", tmp_path / "eval", "--target-fpr", "0.5", *cache)
    assert result.exit_code == 3, result.output
    assert "Skipped 4 test trajectories whose task has no memory entry" in result.output
    assert (tmp_path / "eval" / "evaluation.json").is_file()


# ---------------------------------------------------------------- Ctrl-C (issue 35, item 6)


def test_sigterm_ends_with_one_line_and_leaves_no_lock_behind(
    memory: Path, data: Path, cache: list[str]
) -> None:
    """Issue 45 item 6: SIGTERM (a scheduler stopping the job) ended with status 143, no line and a stale
    `.lock`; now the verb lets go of its lock and temporary files on the way out and says so."""
    good = tree(memory)
    result = interrupted(SIGTERM_WHILE_WRITING, "build-memory", data, "--out", memory, *cache)
    assert (result.returncode, result.stderr, result.stdout) == (143, "error: terminated (SIGTERM)\n", "")
    assert (
        tree(memory) == good and hidden(memory.parent) == []
    )  # the old memory, no lock, nothing half-written


def test_ctrl_c_while_the_command_loads_ends_as_one_while_it_runs(
    memory: Path, data: Path, cache: list[str]
) -> None:
    """SIGINT in the first half second was a KeyboardInterrupt traceback; now both are one line and 130."""
    good = tree(memory)
    args = ("build-memory", data, "--out", memory, *cache)
    for script in (SIGINT_WHILE_LOADING, SIGINT_WHILE_WRITING):
        result = interrupted(script, *args)
        assert (result.returncode, result.stderr, result.stdout) == (130, "error: interrupted (Ctrl-C)\n", "")
        assert tree(memory) == good and hidden(memory.parent) == []  # the old memory, nothing half-written
