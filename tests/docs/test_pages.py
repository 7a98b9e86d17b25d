"""The README is a front door and the pages under docs/ hold the rest: the README's example runs, every
citation of a page names a section it has, every command line shown is the command's own, every page
is in the site's nav. (The site itself is built strictly in tests/docs/test_site.py.)"""

from __future__ import annotations

import functools
import re
import shutil
from pathlib import Path
from typing import Any

import pytest
import typer
import yaml
from synthetic import write_project_dataset

from rfr_viz.cli import reference

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
CITING = ("src", "rfr_viz", "tests", "scripts", "bench", "examples", "docs")
CITATION = re.compile(r"""docs/([\w-]+\.md),?\s+\(?["“]([^"”]+)["”]""")


@functools.cache
def verbs() -> dict[str, Any]:
    return reference.verbs()


@functools.cache
def _options(verb: str) -> set[str]:
    command = verbs()[verb]
    return {option for param in command.get_params(typer.Context(command)) for option in param.opts}


def _blocks(path: Path, languages: tuple[str, ...]) -> list[str]:
    """The fenced code blocks of a Markdown file in one of `languages` ("" for a bare fence)."""
    found = re.findall(r"^```(\w*)\n(.*?)^```", path.read_text(), re.MULTILINE | re.DOTALL)
    return [code for language, code in found if language in languages]


def _headings(page: Path) -> list[str]:
    text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.MULTILINE | re.DOTALL)
    return [m.strip().strip("`") for m in re.findall(r"^#+ (.+)$", text, re.MULTILINE)]


def test_the_readme_is_a_front_door() -> None:
    lines = README.read_text().splitlines()
    assert len(lines) <= 250
    first = _blocks(README, ("bash",))[0]
    assert [line.split("#")[0].strip() for line in first.splitlines()] == [
        "bash scripts/demo.sh",
        "bash scripts/test.sh",
    ]
    assert (
        "docs/evaluation_summary.png" in README.read_text()
        or "docs/contrast_detection.png" in README.read_text()
    )
    assert all((ROOT / link).is_file() for link in re.findall(r"\]\((docs/[^)#]+)", README.read_text()))


def _generated_by_the_comment(example: str) -> list[str]:
    """The `robofailring generate …` command the README's example names as where its data comes from."""
    (command,) = re.findall(r"`robofailring (generate [^`]+)`", example)
    return command.split()


def _live_matches_offline(printed: list[str]) -> None:
    """The example's offline t_det, and the live loop stopping the robot at that very frame."""
    offline = None if printed[0] == "None" else int(printed[0])
    assert printed[1:] == ([] if offline is None else [f"stop the robot at frame {offline}"])


def test_the_readme_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    """The README's Python, as written, on a small dataset in the project's layout with the robot's signals,
    as many successes and split as its comment's `generate` makes (issue 50: it made 2, calibrate needs 19),
    and its live loop stops the robot at the frame the offline run fires at (it passed no signals)."""
    (example,) = _blocks(README, ("python",))
    generate = _generated_by_the_comment(example)
    successes = int(generate[generate.index("--success-episodes") + 1])
    assert generate[generate.index("--tasks") + 1] == "pick_cube"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ROBOFAILRING_CACHE", str(tmp_path / "cache"))
    # generate's split: even episodes train, odd test (episode 1 of each kind is a test run)
    data = write_project_dataset(
        tmp_path / "sim",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=successes,
        length=6,
        signals=True,
    )
    for failure in data.glob(
        "pick_cube_grasp_wp2_episode*"
    ):  # a grasp the cameras miss, the gripper does not
        success = data / failure.name.replace("grasp_wp2", "success")
        for image in success.glob("*.png"):
            shutil.copyfile(image, failure / image.name)
    exec(compile(example, str(README), "exec"), {"__name__": "readme_example"})
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] != "None" and 0 <= int(printed[0]) < 6
    _live_matches_offline(printed)
    assert (tmp_path / "memories" / "sim" / "signals.npz").is_file()  # the memory judges the signals too


@pytest.mark.slow
def test_the_readme_example_runs_on_what_its_comment_generates(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """The README's comment's own `generate` command, smaller frames (the same episodes and split), then
    its Python: calibrate succeeds and the live loop stops the robot where the offline run fires."""
    from typer.testing import CliRunner

    from rfr_viz.cli.app import app

    (example,) = _blocks(README, ("python",))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ROBOFAILRING_CACHE", str(tmp_path / "cache"))
    generated = CliRunner().invoke(
        app, [*_generated_by_the_comment(example), "--image-size", "32", "--frames", "16"]
    )
    assert generated.exit_code == 0, generated.output
    capsys.readouterr()
    exec(compile(example, str(README), "exec"), {"__name__": "readme_example"})
    _live_matches_offline(capsys.readouterr().out.splitlines())


def _cited() -> list[tuple[str, str, str]]:
    """(file, page, section) of every `docs/<page>.md, "<section>"` citation in code, tests and docs."""
    files = [
        path
        for folder in CITING
        for path in (ROOT / folder).rglob("*")
        if path.suffix in (".py", ".md", ".sh")
    ]
    files += [ROOT / "pyproject.toml", ROOT / "constraints.txt", README]
    return [
        (str(path.relative_to(ROOT)), page, " ".join(section.split()))
        for path in files
        for page, section in CITATION.findall(path.read_text())
    ]


def test_citations_name_a_section_of_their_page() -> None:
    cited = _cited()
    assert len(cited) > 15  # the citations were found
    wrong = [
        (where, page, section)
        for where, page, section in cited
        if not (DOCS / page).is_file()
        or not any(h.lower().startswith(section.lower()) for h in _headings(DOCS / page))
    ]
    assert wrong == []


def test_nothing_cites_the_readme_for_a_section() -> None:
    """The README keeps no manual sections: code citing one (`README, "…"`) cites a page of docs/."""
    files = [path for folder in CITING for path in (ROOT / folder).rglob("*.py") if path != Path(__file__)]
    assert [str(p.relative_to(ROOT)) for p in files if re.search(r"README,? \"", p.read_text())] == []


def _commands(text: str) -> list[list[str]]:
    """Each `robofailring VERB …` command of a code block, as its words (comments dropped)."""
    commands = []
    for line in text.splitlines():
        words = line.split("#")[0].split()
        if words[:1] == ["robofailring"] and len(words) > 1 and re.fullmatch(r"[a-z][a-z-]*", words[1]):
            commands.append(words[1:])
    return commands


@pytest.mark.parametrize("page", [README, *PAGES], ids=lambda p: p.name)
def test_command_lines_shown_are_the_commands_own(page: Path) -> None:
    """Every `robofailring VERB --option` in a code block names a verb and options it has."""
    wrong = []
    for block in _blocks(page, ("bash", "")):
        for verb, *words in _commands(block):
            if verb not in verbs():
                wrong.append(verb)
                continue
            wrong += [
                f"{verb} {w}" for w in words if w.startswith("--") and w.split("=")[0] not in _options(verb)
            ]
    assert wrong == []


def test_the_command_line_page_has_every_verb_and_only_its_options() -> None:
    """docs/cli.md's overview (in words, above the generated reference) has an item per verb, whose options
    are the verb's own."""
    overview = (DOCS / "cli.md").read_text().partition(reference.BEGIN)[0]
    rows = re.findall(r"^- `([a-z][a-z-]*)([^`]*)`: ", overview, re.MULTILINE)
    assert sorted(verb for verb, _ in rows) == sorted(verbs())
    wrong = [
        f"{verb} {option}"
        for verb, synopsis in rows
        for option in re.findall(r"--[a-z][a-z-]*", synopsis)
        if option not in _options(verb)
    ]
    assert wrong == []


def _nav_pages(nav: list) -> list[str]:
    pages = []
    for item in nav:
        for value in item.values() if isinstance(item, dict) else [item]:
            pages += _nav_pages(value) if isinstance(value, list) else [value]
    return pages


def test_every_page_is_in_the_sites_nav() -> None:
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    nav = _nav_pages(config["nav"])
    assert sorted(nav) == sorted(page.name for page in PAGES)
    assert config["strict"] is True


def test_the_home_page_lists_every_page() -> None:
    """index.md's table of pages has a row per page of docs/ (the site's nav has them too, above)."""
    listed = set(
        re.findall(r"^\| \[[^\]]+\]\(([\w-]+\.md)\) \|", (DOCS / "index.md").read_text(), re.MULTILINE)
    )
    assert sorted(page.name for page in PAGES if page.name not in listed | {"index.md"}) == []


@pytest.mark.parametrize("page", [README, *PAGES], ids=lambda p: p.name)
def test_pages_cite_no_path_of_this_machine(page: Path) -> None:
    text = page.read_text()
    assert "../shared" not in text and "/work/" not in text
