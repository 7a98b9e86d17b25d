"""docs/cli.md's committed reference is what `rfr_viz.cli.reference` writes from the command now, and the one
command that rewrites it does (another branch adds an option: it reruns that command)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from rfr_viz.cli import reference

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "cli.md"


def test_the_committed_reference_is_the_commands_own() -> None:
    committed = PAGE.read_text(encoding="utf-8")
    assert committed == reference.with_reference(committed), (
        f"docs/cli.md's command-line reference differs from the command's --help: run `{reference.REGENERATE}` "
        "from the checkout's root and commit docs/cli.md"
    )


def test_the_reference_lists_each_verbs_options_under_its_help_panels() -> None:
    """`detect`'s section: its own options under **Options**, then each group's under its panel, in order."""
    committed = PAGE.read_text(encoding="utf-8")
    section = committed.partition("### `detect`")[2].partition("\n### ")[0]
    headings = [line.strip("*") for line in section.splitlines() if line.startswith("**")]
    assert headings == ["Arguments", "Options", "Data", "Detector", "Encoder", "VLM"]
    detector = section.partition("**Detector**")[2].partition("**VLM**")[0]
    assert "- `--memory <path>`: Memory directory. [required]" in detector
    assert "- `--k <int>`: Neighbours retrieved per query. [default: 5]" in detector
    assert "- `--delta <float>`: Threshold δ. [default: (the memory's calibrated δ, else 0.92)]" in detector
    assert "--json" in section.partition("**Options**")[2].partition("**Data**")[0]


def test_the_documented_command_rewrites_a_stale_page(tmp_path: Path) -> None:
    """`python -m rfr_viz.cli.reference PAGE`, as the failure above says, on a page whose reference is stale
    (an option gone, a line added by hand): the page comes back equal to the committed one, prose kept."""
    committed = PAGE.read_text(encoding="utf-8")
    stale = committed.replace("- `--k <int>`: Neighbours retrieved per query. [default: 5]\n", "", 1)
    stale = stale.replace(reference.END, "- `--gone`: an option since removed\n" + reference.END, 1)
    assert stale != committed
    page = tmp_path / "cli.md"
    page.write_text(stale, encoding="utf-8")
    environment = os.environ | {"PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    done = subprocess.run(
        [sys.executable, "-m", "rfr_viz.cli.reference", str(page)],
        capture_output=True,
        text=True,
        env=environment,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == f"{page}: command-line reference rewritten"
    assert page.read_text(encoding="utf-8") == committed
