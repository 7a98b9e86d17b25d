"""The benchmarks the docs cite can run: every script answers `--help` at once and without doing any
work, names the machine it measures on, and every `bench/` path the docs and the README name exists."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from environment import missing

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "bench"
# Runs in the bench-only ManiSkill venv (bench/setup_peer.sh): it imports ManiSkill before parsing
PEER_ONLY = ("peer_generate.py",)
SCRIPTS = sorted(
    path
    for path in [*BENCH.glob("*.py"), *(BENCH / "experiments").glob("*.py")]
    if not path.name.startswith("_") and path.name not in PEER_ONLY
)
# One script's --help, its imports included (the first pays for torch's): generous, for a loaded machine.
# That no work starts is shown by the output: each script prints its machine line before any work.
HELP_SECONDS = 60.0

# One interpreter runs every script as `python bench/<script>.py --help` would, so the heavy imports are
# paid once; it prints one JSON line per script.
DRIVER = """
import contextlib, io, json, runpy, sys, time
for path in sys.argv[1:]:
    sys.argv = [path, "--help"]
    out, code, start = io.StringIO(), None, time.perf_counter()
    try:
        with contextlib.redirect_stdout(out):
            runpy.run_path(path, run_name="__main__")
    except SystemExit as exit:
        code = exit.code
    except BaseException as error:
        code = f"{type(error).__name__}: {error}"
    print(json.dumps({"path": path, "code": code, "out": out.getvalue(), "s": time.perf_counter() - start}))
"""


def test_there_are_benches_to_check() -> None:
    names = {path.name for path in SCRIPTS}
    assert {"bench_scale.py", "bench_replay.py", "bench_video.py", "probe_peer_fusion.py"} <= names


def test_every_bench_answers_help_without_doing_work() -> None:
    """`--help` exits 0 with argparse's usage and nothing else: no machine line, no measurement."""
    environment = os.environ | {"PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    done = subprocess.run(
        [sys.executable, "-c", DRIVER, *map(str, SCRIPTS)],
        capture_output=True,
        text=True,
        env=environment,
        cwd=ROOT,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    answers = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    assert [Path(answer["path"]) for answer in answers] == SCRIPTS
    wrong = {
        Path(answer["path"]).name: (answer["code"], answer["out"][:200], round(answer["s"], 1))
        for answer in answers
        if answer["code"] not in (0, None)
        or not answer["out"].startswith("usage:")
        or answer["s"] > HELP_SECONDS
    }
    assert wrong == {}


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda path: path.name)
def test_every_bench_prints_the_machine_it_measures_on(script: Path) -> None:
    assert "print_machine(" in script.read_text()


@pytest.mark.slow  # imports ManiSkill: seconds
def test_the_peer_generator_answers_help_in_its_own_venv() -> None:
    """In the venv bench_peer.py runs it in (scripts/setup.sh --dev makes it): one bench/setup_peer.sh did not
    finish (no `ready` in it) is missing too, and the full lane fails without it (tests/environment.py)."""
    from bench.bench_peer import default_peer_env

    env_dir = default_peer_env()
    if not (env_dir / "ready").is_file():
        missing(f"no bench-only peer venv ready at {env_dir}: bash bench/setup_peer.sh {env_dir} makes one")
    python = env_dir / "venv" / "bin" / "python"
    done = subprocess.run(
        [str(python), str(BENCH / "peer_generate.py"), "--help"], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0 and done.stdout.startswith("usage:"), done.stderr[-2000:]


def test_every_bench_path_the_docs_name_exists() -> None:
    """`bench/…` paths and `-m bench.…` modules the README, the pages and the committed outputs name."""
    pages = [
        ROOT / "README.md",
        *sorted((ROOT / "docs").glob("*.md")),
        *sorted((ROOT / "docs").glob("*.txt")),
    ]
    pages += [BENCH / "experiments" / "README.md"]
    named = {
        (page.name, found)
        for page in pages
        for found in re.findall(r"\bbench/[\w/]+\.(?:py|sh|txt)\b", page.read_text())
    }
    named |= {
        (page.name, module.replace(".", "/") + ".py")
        for page in pages
        for module in re.findall(r"-m (bench(?:\.\w+)+)(?![.\w<])", page.read_text())
    }
    assert len(named) > 30  # the paths were found
    assert sorted((page, path) for page, path in named if not (ROOT / path).is_file()) == []


def test_documented_bench_commands_run_the_script_as_a_module() -> None:
    """`python -m bench.X` from the checkout's root needs no PYTHONPATH (`-m` puts the checkout on the path,
    the venv has the project); `python bench/X.py` would need it set by hand (`bench._…` imports): the pages,
    the README and the scripts' own usage lines show the first. (The committed outputs record the command
    that made them, PYTHONPATH and all.)"""
    files = [ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *BENCH.rglob("*.py"), *BENCH.rglob("*.md")]
    command = re.compile(r"(?<![\w/=.-])(?:\.venv/bin/)?python3? bench/")
    wrong = [
        f"{path.relative_to(ROOT)}: {line.strip()[:100]}"
        for path in files
        for line in path.read_text().splitlines()
        if command.search(line)
    ]
    assert wrong == []
    records = [
        f"{path.name}: {line.strip()[:100]}"
        for path in (ROOT / "docs").glob("*.txt")
        for line in path.read_text().splitlines()
        if command.search(line) and not re.search(r"PYTHONPATH=\S*(?<!\w)\.(?::|\s|;|$)", line)
    ]
    assert records == []


def test_a_bench_runs_as_documented_without_pythonpath() -> None:
    """The benchmarks page's form, `python -m bench.<script>`, from the checkout's root with no PYTHONPATH."""
    assert "`.venv/bin/python -m bench.<script> …`" in (ROOT / "docs" / "benchmarks.md").read_text()
    environment = {name: value for name, value in os.environ.items() if name != "PYTHONPATH"}
    done = subprocess.run(
        [sys.executable, "-m", "bench.bench_scale", "--help"],
        capture_output=True,
        text=True,
        env=environment,
        cwd=ROOT,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("usage:")
