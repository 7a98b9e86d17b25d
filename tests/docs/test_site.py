"""The documentation site builds with `mkdocs build --strict` (a broken link or anchor, a page out of nav
fails it), its API page lists every curated name, and its command-line page every verb and option."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from environment import missing

import rfr_viz
import robofailring
from rfr_viz.cli.reference import verbs

ROOT = Path(__file__).resolve().parents[2]
DOCS_MODULES = ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python")


@pytest.mark.slow
def test_the_site_builds_strictly(tmp_path: Path) -> None:
    absent = [name for name in DOCS_MODULES if importlib.util.find_spec(name) is None]
    if absent:
        missing(f"the docs extra is not installed ({', '.join(absent)}): pip install -e '.[docs]'")
    site = tmp_path / "site"
    environment = os.environ | {"NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": os.pathsep.join(sys.path)}
    built = subprocess.run(
        [
            sys.executable,
            "-m",
            "mkdocs",
            "build",
            "--strict",
            "--config-file",
            str(ROOT / "mkdocs.yml"),
            "--site-dir",
            str(site),
        ],
        capture_output=True,
        text=True,
        env=environment,
        cwd=ROOT,
        timeout=600,
    )
    assert built.returncode == 0, built.stderr[-4000:]
    assert "WARNING" not in built.stderr
    api = (site / "api" / "index.html").read_text()
    ids = set(re.findall(r'id="((?:robofailring|rfr_viz)\.\w+)"', api))
    assert [n for n in robofailring.__all__ if f"robofailring.{n}" not in ids] == []
    assert [n for n in rfr_viz.__all__ if f"rfr_viz.{n}" not in ids] == []
    cli = (site / "cli" / "index.html").read_text()
    for verb, command in verbs().items():
        assert f'id="{verb}"' in cli or f"<code>{verb}</code>" in cli, verb
        for param in command.params:
            for option in (o for o in param.opts if o.startswith("--")):
                assert f"{option}" in cli, f"{verb} {option}"
    for page in ("index.html", "data/index.html", "recording/index.html", "rules/index.html"):
        assert (site / page).is_file()


@pytest.mark.slow
def test_the_sites_settings_fail_a_broken_link_an_anchor_and_a_page_out_of_nav(tmp_path: Path) -> None:
    """mkdocs.yml's strict validation, on a two-page site with one of each fault."""
    if importlib.util.find_spec("mkdocs") is None:
        missing("the docs extra is not installed (mkdocs): pip install -e '.[docs]'")
    import yaml

    ours = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text("# Home\n\n[gone](gone.md), [no anchor](#nowhere)\n")
    (docs / "orphan.md").write_text("# Not in nav\n")
    config = {"site_name": "t", "docs_dir": str(docs), "strict": ours["strict"], "nav": ["index.md"]}
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(config | {"validation": ours["validation"]}))
    built = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--config-file", str(tmp_path / "mkdocs.yml")],
        capture_output=True,
        text=True,
        env=os.environ | {"NO_MKDOCS_2_WARNING": "1"},
        cwd=tmp_path,
        timeout=300,
    )
    assert built.returncode != 0
    assert "'gone.md'" in built.stderr and "'#nowhere'" in built.stderr and "orphan.md" in built.stderr
