"""`--help` as docs/cli.md describes it: each option group's options under the group's own panel, every
default stated one way (typer's `[default: …]`), and every option's help shown whole (Rich markup reads
`[z_0 ‖ z_t]` as a tag and drops it unless escaped)."""

from __future__ import annotations

import re
from typing import Any

import pytest
from rich.text import Text
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from rfr_viz.cli.reference import verbs

# Each group's panel, as docs/cli.md's overview names the groups
PANELS = {
    "data": "Data",
    "recipe": "Memory recipe",
    "detector": "Detector",
    "scoring": "Detector",
    "placement": "Encoder",
    "threshold_policy": "Thresholds",
    "vlm": "VLM",
    "recordings": "Recordings",
}
# A default said in the help's words rather than by typer's `[default: …]` (show_default= says it)
DEFAULT_IN_WORDS = re.compile(r"\(default\b|\bdefault:|\bdefault (?:all|pixels|\S+/)|^default", re.IGNORECASE)


def _help(*args: str) -> str:
    done = CliRunner().invoke(app, [*args, "--help"], env={"TERMINAL_WIDTH": "200", "COLUMNS": "200"})
    assert done.exit_code == 0, done.output
    return done.output


def _panels(output: str) -> dict[str, list[str]]:
    """The options `--help` lists under each panel's box."""
    found: dict[str, list[str]] = {}
    current = None
    for line in output.splitlines():
        title = re.match(r"╭─ (.+?) ─", line)
        if title:
            current = found.setdefault(title.group(1), [])
        elif current is not None:
            option = re.match(
                r"│ {1,4}(?:\* +)?(--[a-z][a-z-]*)", line
            )  # a help's wrapped line is indented more
            current += [option.group(1)] if option else []
    return found


def _params() -> list[tuple[str, Any]]:
    return [
        (name, param) for name, command in verbs().items() for param in command.params if param.name != "help"
    ]


def test_evaluate_lists_each_group_under_its_panel() -> None:
    panels = _panels(_help("evaluate"))
    assert list(panels) == [
        "Arguments",
        "Options",
        "Data",
        "Memory recipe",
        "Detector",
        "Encoder",
        "Thresholds",
    ]
    assert panels["Thresholds"] == ["--target-fpr", "--band", "--fusion", "--band-scope"]
    assert panels["Memory recipe"][:3] == ["--encoder", "--failure-frames", "--pairing"]
    assert "--signal-start-weight" in panels["Memory recipe"]
    assert panels["Data"] == ["--labels", "--task", "--views", "--vocabulary"]
    assert {"--k", "--modality"} <= set(panels["Detector"])
    assert panels["Encoder"] == ["--cache-dir", "--device", "--runtime", "--ray"]
    assert {"--out", "--test-data", "--growth"} <= set(panels["Options"])


def test_every_group_option_of_every_verb_is_under_its_groups_panel() -> None:
    """Read from the commands typer builds: a group's option is in the group's panel, a verb's own in none."""
    wrong = []
    for name, command in verbs().items():
        groups = getattr(command.callback, "option_groups", {})
        assert set(groups) <= set(PANELS), (
            f"{name}: a group with no panel named here: {set(groups) - set(PANELS)}"
        )
        of_group = {param: panel for value in groups.values() for param, panel in value.panels().items()}
        assert set(of_group.values()) <= set(PANELS.values())
        for param in command.params:
            if param.param_type_name != "option" or param.name == "help":
                continue
            expected = of_group.get(param.name)
            if getattr(param, "rich_help_panel", None) != expected:
                wrong.append((name, param.opts[0], getattr(param, "rich_help_panel", None), expected))
    assert wrong == []


def test_the_help_shows_norm_timm_and_name_glob() -> None:
    """The issue's three: `--pairing`'s norm([z_0 ‖ z_t]) was dropped as a Rich tag; `--encoder` lacked
    `timm:`, `--signals` lacked `NAME:GLOB`."""
    output = " ".join(re.sub(r"[│╭╮╰╯─]", " ", _help("build-memory")).split())
    assert "`concat`, the paper's norm([z_0 ‖ z_t])." in output
    assert "`timm:<model>[:<checkpoint path>]`" in output
    assert "`NAME:GLOB`" in output and "`observation.state:gripper*`" in output


@pytest.mark.parametrize("verb", sorted(verbs()))
def test_no_help_text_loses_words_to_rich_markup(verb: str) -> None:
    """What `--help` prints of each help (Rich markup read) is the text written, less its `\\[` escapes."""
    lost = [
        (param.opts[0] if param.opts else param.name, param.help)
        for name, param in _params()
        if name == verb
        and param.help
        and Text.from_markup(param.help).plain != param.help.replace("\\[", "[")
    ]
    assert lost == [], "escape a `[` that Rich reads as a tag as `\\\\[`"


def test_defaults_are_stated_one_way() -> None:
    """No option's help says its default in words: a default is typer's `[default: …]`, from the option's
    default value or, where that is None, its `show_default` text."""
    worded = sorted(
        {(param.opts[0], param.help) for _, param in _params() if DEFAULT_IN_WORDS.search(param.help or "")}
    )
    assert worded == []
    shown = {
        param.opts[0]: param.show_default for _, param in _params() if isinstance(param.show_default, str)
    }
    assert shown["--delta"] == "the memory's calibrated δ, else 0.92"
    assert shown["--pairing"] == "change; growing a memory with --add-to keeps its own"


def test_a_verb_without_groups_keeps_typers_two_panels() -> None:
    assert list(_panels(_help("open"))) == ["Arguments", "Options"]
