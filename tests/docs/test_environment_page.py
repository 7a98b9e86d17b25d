"""docs/environment.md names every environment variable the code reads: the library, the recording tools,
the benchmarks, the scripts and the tests' own set-up (`tests/environment.py`, `tests/conftest.py`)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "environment.md"
PYTHON = [
    *(ROOT / "src" / "robofailring").rglob("*.py"),
    *(ROOT / "rfr_viz").rglob("*.py"),
    *(ROOT / "bench").rglob("*.py"),
    ROOT / "tests" / "environment.py",
    ROOT / "tests" / "conftest.py",
]
SHELL = [*(ROOT / "scripts").glob("*.sh"), *(ROOT / "bench").glob("*.sh")]
# a variable read by name: os.environ.get("X"), os.getenv("X"), os.environ["X"], os.environ.setdefault("X", …)
READ = re.compile(
    r"""(?:environ\.get|getenv|environ\.setdefault)\(\s*["']([A-Z][A-Z0-9_]+)["']|environ\[["']([A-Z][A-Z0-9_]+)["']\]"""
)
# names set in a loop: for _variable in ("OMP_NUM_THREADS", …): os.environ.setdefault(_variable, "1")
LOOPED = re.compile(r"for (\w+) in \(([^)]*)\):\s*\n\s*os\.environ\.setdefault\(\1")
# the project's own, wherever named (a constant such as API_KEY_ENV = "ROBOFAILRING_VLM_API_KEY")
OWN = re.compile(r"""["'](ROBOFAILRING_[A-Z0-9_]+)["']""")
SHELL_READ = re.compile(r"\$\{?(ROBOFAILRING_[A-Z0-9_]+)|^export (ROBOFAILRING_[A-Z0-9_]+)=", re.MULTILINE)


def _read_by_the_code() -> set[str]:
    names: set[str] = set()
    for path in PYTHON:
        text = path.read_text()
        names |= {a or b for a, b in READ.findall(text)}
        names |= {
            name for _, group in LOOPED.findall(text) for name in re.findall(r"[\"']([A-Z_]+)[\"']", group)
        }
        names |= set(OWN.findall(text))
    for path in SHELL:
        names |= {a or b for a, b in SHELL_READ.findall(path.read_text())}
    return names


def test_every_variable_the_code_reads_is_on_the_page() -> None:
    names = _read_by_the_code()
    assert {
        "ROBOFAILRING_PROGRESS",
        "ROBOFAILRING_CACHE",
        "ROBOFAILRING_VLM_API_KEY",
        "OMP_NUM_THREADS",
    } <= names
    documented = set(re.findall(r"`([A-Z][A-Z0-9_]+)`", PAGE.read_text()))
    assert sorted(names - documented) == []
