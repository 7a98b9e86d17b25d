"""One error path (issue 20): no verb catches errors; the app maps every error to one line and a status.

The verbs' modules are read as source (no `try` in a command); each error a verb used to catch
itself is provoked through the real `robofailring` app and must end in one `error:` line.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from fault_helpers import cli, refused
from vlm_server import chat_server

import rfr_viz.cli.jobs
import rfr_viz.cli.live
import rfr_viz.cli.replay
import robofailring.cli.verbs
from robofailring.cli.exit_codes import BAD_INPUT, ERROR

VERB_MODULES = [robofailring.cli.verbs, rfr_viz.cli.replay, rfr_viz.cli.jobs, rfr_viz.cli.live]


def _commands(tree: ast.Module) -> list[ast.FunctionDef]:
    """The functions decorated `@<app>.command(...)`."""
    return [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef)
        and any(
            isinstance(d, ast.Call) and isinstance(d.func, ast.Attribute) and d.func.attr == "command"
            for d in node.decorator_list
        )
    ]


@pytest.mark.parametrize("module", VERB_MODULES, ids=lambda m: m.__name__)
def test_no_verb_catches_errors_of_its_own(module: object) -> None:
    tree = ast.parse(Path(str(getattr(module, "__file__", ""))).read_text())
    commands = _commands(tree)
    assert commands, "no command found: the test reads the wrong module"
    wrapped = [c.name for c in commands if any(isinstance(n, ast.Try | ast.TryStar) for n in ast.walk(c))]
    assert wrapped == []
    helpers = {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
    assert not helpers & {"exit_with_error", "fail"}  # the group is the one place that prints an error


def test_bad_settings_are_one_line_and_status_2(tmp_path: Path) -> None:
    nowhere, episode = tmp_path / "no-memory", tmp_path / "pick_cube_grasp_wp2_episode0"
    data = tmp_path / "data"
    data.mkdir()
    refused(
        cli("generate", "--out", tmp_path / "gen", "--tasks", "juggle"),
        BAD_INPUT,
        "unknown task(s)",
        "juggle",
    )
    refused(
        cli("watch", episode, "--memory", nowhere, "--speed", "-1"),
        BAD_INPUT,
        "--speed must be a finite number ≥ 0, got -1",
    )
    refused(cli("watch", episode, "--memory", nowhere, "--fps", "0"), BAD_INPUT, "--fps", "got 0")
    refused(
        cli("compare", data, "--memory", nowhere, "--out", tmp_path / "rec"),
        BAD_INPUT,
        "at least two memories",
        "got 1",
    )
    refused(
        cli("compare-encoders", data, "--encoder", "pixels", "--out", tmp_path / "cmp"),
        BAD_INPUT,
        "at least two encoders",
        "got 1",
    )
    refused(cli("explain", tmp_path / "trace.json"), BAD_INPUT, "explain needs --vlm-url and --vlm-model")
    refused(
        cli("detect", episode, "--memory", nowhere, "--vlm-url", "http://localhost:1/v1"),
        BAD_INPUT,
        "--vlm-url and --vlm-model go together",
    )
    refused(cli("open", tmp_path / "none.rrd"), BAD_INPUT, "no recording at")


@pytest.mark.slow  # an end-to-end run of every verb: the full lane
def test_environment_errors_are_one_line_and_status_1(
    memory: Path, data: Path, cache: list[str], tmp_path: Path
) -> None:
    episode = data / "pick_cube_grasp_wp2_episode0"
    refused(
        cli("watch", episode, "--memory", memory, "--connect", "rerun+http://127.0.0.1:9/proxy", *cache),
        ERROR,
        "127.0.0.1",
    )
    refused(
        cli("watch", episode, "--memory", memory, "--connect", "http:/nowhere", *cache),
        BAD_INPUT,
        "viewer URL 'http:/nowhere'",
    )
    detected = cli("detect", episode, "--memory", memory, "--delta", "-1", "--json", *cache)
    assert detected.exit_code == 0, detected.output
    trace = tmp_path / "trace.json"
    trace.write_text(detected.stdout)
    assert json.loads(detected.stdout)["report"] is not None
    with chat_server(("status", 400), ("status", 400), ("status", 400)) as server:
        named = ("--data-root", data)  # the folder of the report's images (the memory's and the run's)
        explained = cli("explain", trace, "--vlm-url", server.url, "--vlm-model", "m", "--json", *named)
    refused(explained, ERROR, "the VLM call failed", "HTTP 400")
    assert "HTTP 400" in json.loads(explained.stdout)["error"]  # the JSON still says why, before the error


_NOISY_DETECT = """
import logging, sys
import robofailring.jobs.detect as job
from rfr_viz.cli.app import main
real = job.detector_from
def noisy(*args, **kwargs):
    logging.error("Failed to download weights for tag 'openai'")  # as open_clip logs, on the root logger
    logging.getLogger("rerun").warning("a library's own warning")
    return real(*args, **kwargs)
job.detector_from = noisy
sys.argv = ["robofailring", "detect", sys.argv[1], "--memory", sys.argv[2]]
main()
"""


@pytest.mark.parametrize("shown", ["", "all"])
def test_libraries_log_lines_stay_out_of_the_commands_output(
    memory: Path, data: Path, tmp_path: Path, shown: str
) -> None:
    """open_clip's `ERROR:root:` line before the error that explains it, and other libraries' own log
    lines, are not printed (issue 35, item 9) unless ROBOFAILRING_LOG=all; the command's own warnings are."""
    env = {**os.environ, "ROBOFAILRING_PROGRESS": "0", "ROBOFAILRING_LOG": shown}
    missing = tmp_path / "no-such-episode"
    run = subprocess.run(
        [sys.executable, "-c", _NOISY_DETECT, str(missing), str(memory)],
        capture_output=True,
        text=True,
        env=env,
        check=False,
        timeout=300,
    )
    assert run.returncode == BAD_INPUT, run.stderr
    lines = run.stderr.splitlines()
    assert lines[-1].startswith("error: ") and str(missing) in lines[-1]
    assert any(line.startswith("warning: the ") and "not calibrated" in line for line in lines)  # its own
    noise = [line for line in lines if "Failed to download" in line or "a library's own warning" in line]
    assert noise == (
        [] if shown != "all" else ["Failed to download weights for tag 'openai'", "a library's own warning"]
    )
