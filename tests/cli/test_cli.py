"""The CLI verbs, run as a user would: build-memory, then detect --json."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from synthetic import write_episode
from typer.testing import CliRunner

from robofailring.cli.verbs import app

runner = CliRunner()


def test_build_memory_then_detect_json(aha_dataset: Path, tmp_path: Path) -> None:
    memory = tmp_path / "memory"
    cache = tmp_path / "cache"
    built = runner.invoke(
        app, ["build-memory", str(aha_dataset), "--out", str(memory), "--cache-dir", str(cache)]
    )
    assert built.exit_code == 0, built.output
    # dense by default: of frames 1-5 of each of the 36 failure views (6 frames, onsets not known), those
    # that moved away from the run's first frame, each view's end entry always
    said = re.search(r"failure memory: dense, (\d+) entries from 36 failure views", built.output)
    assert said is not None, built.output
    count = int(said.group(1))
    assert 36 < count <= 180 and f"{count} entries" in built.output
    manifest = json.loads((memory / "manifest.json").read_text())
    assert {"format_version", "encoder", "dim", "count"} <= set(manifest) and manifest["count"] == count
    assert (manifest["failure_frames"], manifest["failure_step"]) == ("dense", 0.002)

    episode = write_episode(tmp_path / "pick_cube_grasp_wp2_episode9", "pick_cube", "grasp_wp2", length=6)
    result = runner.invoke(
        app,
        [
            "detect",
            str(episode),
            "--memory",
            str(memory),
            "--delta",
            "0.5",
            "--k",
            "2",
            "--json",
            "--cache-dir",
            str(cache),
        ],
    )
    assert result.exit_code == 0, result.output
    trace = json.loads(result.stdout)
    assert trace["task"] == "pick_cube" and trace["length"] == 6 and trace["delta"] == 0.5 and trace["k"] == 2
    assert set(trace["views"]) == {"front", "overhead", "wrist"}
    front = trace["views"]["front"]
    assert len(front["similarity"]) == 6 and len(front["top_neighbor"]) == 6
    assert front["top_neighbor"][0]["task"] == "pick_cube"
    assert {"task", "symbol", "view", "episode"} <= set(front["top_neighbor"][0])
    assert all(0 < n["frame"] < n["length"] == 6 for n in front["top_neighbor"])  # the moment each matched
    first_over = min(
        (
            t
            for v in trace["views"].values()
            for t, s in enumerate(v["similarity"])
            if s is not None and s >= 0.5
        ),
        default=None,
    )
    assert trace["t_det"] == first_over
    assert trace["detected_view"] in trace["views"]


def test_cli_errors_are_one_clear_line(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    result = runner.invoke(app, ["build-memory", str(data), "--out", str(tmp_path / "m")])
    assert result.exit_code == 2
    assert "matches no known dataset layout" in result.output
    result = runner.invoke(app, ["detect", str(tmp_path), "--memory", str(tmp_path / "none")])
    assert result.exit_code == 2 and "manifest.json is missing" in result.output
    result = runner.invoke(app, ["build-memory", str(data), "--out", str(tmp_path / "m"), "--encoder", "vgg"])
    assert result.exit_code == 2 and "unknown encoder spec 'vgg'" in result.output


def test_console_script_is_installed() -> None:
    result = subprocess.run(
        [Path(sys.executable).with_name("robofailring"), "--help"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0 and "build-memory" in result.stdout


@pytest.mark.slow  # simulation: the full lane only
def test_generate_writes_a_loadable_dataset(tmp_path: Path) -> None:
    from robofailring import load_dataset

    out = tmp_path / "sim"
    args = [
        "generate",
        "--out",
        str(out),
        "--tasks",
        "pick_cube",
        "--episodes",
        "1",
        "--image-size",
        "32",
        "--frames",
        "6",
        "--workers",
        "1",
        "--success-episodes",
        "2",
    ]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "dataset" in result.output and "episodes" in result.output
    trajectories = list(load_dataset(out))
    assert len(trajectories) == 9 and {t.task for t in trajectories} == {"pick_cube"}
    assert all(t.length == 6 for t in trajectories)
    assert sum(t.symbol is None for t in trajectories) >= 2  # the extra success runs (and any failed attempt)
    # a folder that is not a dataset is never overwritten
    precious = tmp_path / "precious"
    precious.mkdir()
    (precious / "notes.txt").write_text("keep me")
    result = runner.invoke(
        app, ["generate", "--out", str(precious), "--tasks", "pick_cube", "--episodes", "1"]
    )
    assert result.exit_code == 2 and (precious / "notes.txt").read_text() == "keep me"


def test_detect_leave_one_out_hides_the_episode(aha_dataset: Path, tmp_path: Path) -> None:
    memory = tmp_path / "memory"
    cache = ["--cache-dir", str(tmp_path / "cache")]
    assert runner.invoke(app, ["build-memory", str(aha_dataset), "--out", str(memory), *cache]).exit_code == 0
    episode = aha_dataset / "pick_cube_wrong_object_episode1"
    plain = json.loads(
        runner.invoke(app, ["detect", str(episode), "--memory", str(memory), "--json", *cache]).stdout
    )
    assert plain["views"]["front"]["top_neighbor"][-1]["episode"] == episode.name
    assert plain["views"]["front"]["similarity"][-1] == 1.0
    held_out = runner.invoke(
        app, ["detect", str(episode), "--memory", str(memory), "--json", "--leave-one-out", *cache]
    )
    trace = json.loads(held_out.stdout)
    assert all(
        top["episode"] != episode.name for view in trace["views"].values() for top in view["top_neighbor"]
    )
    assert trace["views"]["front"]["similarity"][-1] < 1.0


def test_memory_from_a_checkpoint_without_its_spec_says_what_to_pass(tmp_path: Path) -> None:
    import numpy as np

    from robofailring import FailureMemory
    from robofailring.memory.failure import MemoryEntry

    entry = MemoryEntry(task="t", symbol="slip_wp3", episode="e", view="front", start="a.png", end="b.png")
    vectors = np.ones((1, 32), np.float32) / np.sqrt(32)
    FailureMemory(vectors, [entry], encoder="open_clip:TinyViT-test:file-0123abcd").save(tmp_path / "memory")
    episode = write_episode(tmp_path / "ep", "t", None, length=3)
    result = runner.invoke(app, ["detect", str(episode), "--memory", str(tmp_path / "memory"), "--task", "t"])
    assert result.exit_code == 2
    assert "--encoder open_clip:TinyViT-test:/path/to/the/same/checkpoint" in result.output


def test_detect_says_which_frames_uneven_views_leave_unscored(aha_dataset: Path, tmp_path: Path) -> None:
    memory = tmp_path / "memory"
    cache = ["--cache-dir", str(tmp_path / "cache")]
    assert runner.invoke(app, ["build-memory", str(aha_dataset), "--out", str(memory), *cache]).exit_code == 0
    episode = write_episode(tmp_path / "query", "pick_cube", None, length=5, views=("overhead", "wrist"))
    write_episode(episode, "pick_cube", None, length=8, views=("front",))
    write_episode(tmp_path / "query", "pick_cube", None, length=1, views=("side",))
    result = runner.invoke(
        app, ["detect", str(episode), "--memory", str(memory), "--task", "pick_cube", "--json", *cache]
    )
    assert result.exit_code == 3, result.output  # a view skipped: listed, status 3 as in every verb
    trace = json.loads(result.stdout)
    assert (
        trace["length"] == 5
        and trace["unscored_frames"] == {"front": 3}
        and trace["skipped_views"] == ["side"]
    )
    assert len(trace["views"]["front"]["similarity"]) == 5
    assert "view front has 8 frames; the last 3 are not scored" in result.stderr
    assert "view side: 1 frame(s), fewer than 2: not scored" in result.stderr


def test_out_of_range_settings_are_refused_before_any_work(aha_dataset: Path, tmp_path: Path) -> None:
    from rfr_viz.cli.app import app as tool_app

    memory = tmp_path / "memory"
    cache = ["--cache-dir", str(tmp_path / "cache")]
    assert runner.invoke(app, ["build-memory", str(aha_dataset), "--out", str(memory), *cache]).exit_code == 0
    episode = str(aha_dataset / "pick_cube_wrong_object_episode1")
    cases = [
        (app, ["detect", episode, "--memory", str(memory), "--delta", "1.5"], "δ must lie in [-1, 1]"),
        (app, ["detect", episode, "--memory", str(memory), "--k", "0"], "whole number from 1 to 1024, got 0"),
        (app, ["calibrate", str(aha_dataset), "--memory", str(memory), "--target-fpr", "2"], "target FPR"),
        (
            tool_app,
            ["evaluate", str(aha_dataset), "--out", str(tmp_path / "eval"), "--k", "0"],
            "from 1 to 1024",
        ),
        (app, ["detect", episode, "--memory", str(memory), "--k", "99999999999999999999"], "from 1 to 1024"),
        (
            tool_app,
            ["replay", episode, "--memory", str(memory), "--out", str(tmp_path / "rec"), "--delta", "-3"],
            "δ",
        ),
    ]
    for command, args, message in cases:
        result = runner.invoke(command, [*args, *cache])
        assert result.exit_code == 2 and message in result.output, (args, result.output)
    assert not (tmp_path / "eval").exists() and not list((tmp_path / "rec").glob("*.rrd"))
    manifest = json.loads((memory / "manifest.json").read_text())
    assert manifest.get("calibration") is None  # the refused calibration wrote nothing


LIBRARY_VERBS = ["generate", "build-memory", "detect", "calibrate", "memory-info", "train-encoder"]
RECORDING_VERBS = [
    "replay",
    "compare",
    "open",
    "share",
    "evaluate",
    "review",
    "compare-encoders",
    "demo",
    "triage",
]


def test_one_command_composed_from_apps_that_stay_as_they_are() -> None:
    """`robofailring` is assembled once, by composition: importing it adds no verb to the library's app."""
    import typer.main

    from rfr_viz.cli.app import app as full

    assert [c.name for c in app.registered_commands] == LIBRARY_VERBS
    group = typer.main.get_command(full)
    assert isinstance(group, typer.main.TyperGroup)
    assert list(group.commands) == [*LIBRARY_VERBS, *RECORDING_VERBS, "explain", "watch"]
    result = subprocess.run(
        [Path(sys.executable).with_name("robofailring"), "--help"],
        capture_output=True,
        text=True,
        check=False,
    )
    listed = [
        line.split()[1] for line in result.stdout.splitlines() if line.startswith("│ ") and line.split()[1:2]
    ]
    assert [verb for verb in listed if verb in group.commands] == list(group.commands)


def test_build_memory_takes_the_task_of_an_episode_folder_it_suggests(tmp_path: Path) -> None:
    """The error that asks for --task is one build-memory can act on."""
    from synthetic import write_episode

    episode = write_episode(tmp_path / "episode", "pick_cube", "grasp_wp2", length=4)
    runner = CliRunner()
    asked = runner.invoke(app, ["build-memory", str(episode), "--out", str(tmp_path / "m")])
    assert asked.exit_code == 2 and "--task" in asked.output
    told = runner.invoke(
        app, ["build-memory", str(episode), "--out", str(tmp_path / "m"), "--task", "pick_cube"]
    )
    # unlabelled: neither a failure nor a success, the error every layout without outcomes gives
    assert told.exit_code == 2 and "needs to know which episodes failed" in told.output


def test_build_memory_and_memory_info_count_success_views_alike(tmp_path: Path) -> None:
    """build-memory said "14 views" (success views and failure starts together) where memory-info
    said 4 success views (issue 35, item 9): both now count success views, and build-memory the starts apart."""
    from synthetic import write_project_dataset

    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2)
    runner = CliRunner()
    built = runner.invoke(app, ["build-memory", str(data), "--out", str(tmp_path / "m"), "--split", "train"])
    assert built.exit_code == 0, built.output
    info = runner.invoke(app, ["memory-info", str(tmp_path / "m"), "--json"])
    counted = json.loads(info.stdout)["successes"]["runs"]
    line = next(line for line in built.output.splitlines() if line.startswith("success memory:"))
    assert f"{counted} success views and " in line and " failure starts over 1 tasks" in line
    starts = int(line.split(" success views and ")[1].split()[0])
    assert counted == 3 and starts == 3  # one success and one failure run of 3 views in the train split
