"""Ctrl-C at any moment of the command's start (issue 50): one `error: interrupted (Ctrl-C)` line and status
130, never a traceback, a bare 130 or typer's "Aborted!". Each moment typer and the command pass through is
hit on purpose (a SIGINT sent from inside), then real SIGINTs at many moments of the console script's start."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

INTERRUPTED = (130, "error: interrupted (Ctrl-C)\n", "")

CTRL_C_AT = """
import os, signal, sys
where = sys.argv[1]
def ctrl_c(*args, **kwargs):
    os.kill(os.getpid(), signal.SIGINT)
    raise AssertionError("the SIGINT was not delivered")
if where == "logging":  # the command's first import
    import importlib.abc
    class CtrlC(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "logging":
                ctrl_c()
    sys.meta_path.insert(0, CtrlC())
else:
    import typer.core, typer.main
    if where == "building":  # typer turning the verb apps into click commands
        typer.main.get_command = ctrl_c
    elif where == "parsing":  # click parsing the command line, before the verb is invoked
        typer.core.TyperGroup.make_context = ctrl_c
sys.argv[1:] = sys.argv[2:]
from rfr_viz.cli.app import main  # what the console script runs
sys.exit(main())
"""


def _env() -> dict[str, str]:
    return {**os.environ, "ROBOFAILRING_PROGRESS": "0"}


@pytest.mark.parametrize("where", ["logging", "building", "parsing"])
def test_a_ctrl_c_at_each_moment_of_the_start_is_one_line_and_130(where: str, tmp_path: Path) -> None:
    """Before: `logging` loading, a traceback; typer building the command, a traceback; click parsing the
    arguments, status 130 without a word."""
    command = [sys.executable, "-c", CTRL_C_AT, where, "memory-info", str(tmp_path)]
    done = subprocess.run(command, capture_output=True, text=True, env=_env(), check=False)
    assert (done.returncode, done.stderr, done.stdout) == INTERRUPTED


def _before_the_script(returncode: int, stderr: str, launcher: Path) -> bool:
    """A SIGINT the interpreter got before the console script's first line: killed by it with no word, or
    a traceback from Python's own start (`site`) that never passes through the script."""
    return (returncode == -signal.SIGINT and not stderr) or (
        "Traceback" in stderr and str(launcher) not in stderr
    )


def test_real_ctrl_c_at_many_moments_of_the_first_moments(pixels_memory_dir: Path) -> None:
    """SIGINT sent to the console script at moments spread over its start (0.05 s on, up to the time it
    takes to load and run `memory-info`): each is one line and 130."""
    launcher = Path(sys.executable).with_name("robofailring")
    command = [sys.executable, str(launcher), "memory-info", str(pixels_memory_dir)]
    began = time.monotonic()
    whole = subprocess.run(command, capture_output=True, text=True, env=_env(), check=False)
    took = time.monotonic() - began  # where the signals go, never asserted on
    assert whole.returncode == 0, whole.stderr
    # twelve moments spread over the start, then finer ones between them until six land in the command: on a
    # loaded machine one run's start is not the next one's, and a SIGINT before the script or after the
    # command's end says nothing of it (the outcomes of those that land are all asserted)
    spread = [0.05 + (took - 0.05) * step / 11 for step in range(12)]
    finer = [0.05 + (took - 0.05) * share / 22 for share in (*range(1, 23, 2), *range(1, 45, 2))]
    counted: list[tuple[float, tuple[int, str, str]]] = []
    for number, moment in enumerate([*spread, *finer]):
        if number >= len(spread) and len(counted) >= 6:
            break
        process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env()
        )
        time.sleep(moment)
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
        stdout, stderr = process.communicate(timeout=120)
        if process.returncode == 0 or _before_the_script(process.returncode, stderr, launcher):
            continue  # done before the signal, or signalled before the script ran: not the command's
        counted.append((moment, (process.returncode, stderr, stdout)))
    assert len(counted) >= 6, counted
    after_the_output = (
        *INTERRUPTED[:2],
        whole.stdout,
    )  # as the command ends: its output whole, then the line
    assert all(outcome in (INTERRUPTED, after_the_output) for _, outcome in counted), counted


CTRL_C_AS_IT_ENDS = """
import os, signal, sys, threading, time
where = sys.argv[1]
def ctrl_c():
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.2)  # the signal is delivered and handled meanwhile
sys.argv[1:] = sys.argv[2:]
from rfr_viz.cli.app import main  # what the console script runs
if where == "atexit":  # the interpreter running its exit functions
    import atexit
    atexit.register(ctrl_c)
try:
    sys.exit(main())
finally:
    if where == "script":  # the console script's line, its output all printed
        ctrl_c()
    elif where == "threads":  # the interpreter waiting for a thread still running
        threading.Thread(target=time.sleep, args=(0.4,)).start()
        threading.Timer(0.1, ctrl_c).start()
"""


@pytest.mark.parametrize("where", ["script", "threads", "atexit"])
def test_a_ctrl_c_as_the_command_ends_is_one_line_and_130(where: str, pixels_memory_dir: Path) -> None:
    """Outside use round 6, M1: a Ctrl-C after the command printed all its output (the console script
    ending, the interpreter exiting) killed the process by the signal itself: status 130 (or -2) and no
    word. It is now the same one line and 130 as any other, after the command's whole output."""
    command = [sys.executable, "-c", CTRL_C_AS_IT_ENDS, where, "memory-info", str(pixels_memory_dir)]
    done = subprocess.run(command, capture_output=True, text=True, env=_env(), check=False)
    assert (done.returncode, done.stderr) == INTERRUPTED[:2], done
    assert str(pixels_memory_dir) in done.stdout  # the command's output, whole, before the line
