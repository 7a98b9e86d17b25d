"""The command line's reference as Markdown, written from the `robofailring` app itself.

The docs site's command-line page (docs/cli.md) is completed with it when the site is built
(`scripts/docs_hooks.py`), so every verb, argument and option it lists is the command's own, with
the command's own help and defaults: the reference cannot drift from the code.
"""

from __future__ import annotations

from typing import Any, Final

import typer

from rfr_viz.cli.app import app

#: The line in docs/cli.md that the generated reference replaces.
MARKER: Final = "<!-- cli-reference -->"


def verbs() -> dict[str, Any]:
    """Every verb of the `robofailring` command by name (typer's click commands), as `--help` lists them."""
    group: Any = typer.main.get_command(app)
    context = typer.Context(group, info_name="robofailring")
    return {name: group.get_command(context, name) for name in group.list_commands(context)}


def _line(text: str) -> str:
    """Help text as one line of Markdown."""
    return " ".join(text.split())


def verb_reference(name: str, command: Any, *, level: int = 3) -> str:
    """One verb: its help, its usage line, and a list of its arguments and options with their help."""
    context = typer.Context(command, info_name=f"robofailring {name}")
    params = [p for p in command.get_params(context) if p.name != "help"]
    arguments = " ".join((p.name or "").upper() for p in params if p.param_type_name == "argument")
    lines = [f"{'#' * level} `{name}`", "", _line(command.help or ""), ""]
    lines += ["```", f"robofailring {name} [OPTIONS] {arguments}".rstrip(), "```", ""]
    for param in params:
        record = param.get_help_record(context)
        if record is not None:
            lines.append(f"- `{_line(record[0])}`: {_line(record[1])}")
    return "\n".join(lines) + "\n"


def cli_reference(*, level: int = 3) -> str:
    """Every verb's reference, in `--help`'s order."""
    return "\n".join(verb_reference(name, command, level=level) for name, command in verbs().items())
