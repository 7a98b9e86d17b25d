"""The command line's reference as Markdown, written from the `robofailring` app itself into docs/cli.md.

docs/cli.md is committed with the reference in it, between `BEGIN` and `END`: every verb, argument and
option, under the panels `--help` lists them in, with the command's own help and defaults, so the page
cannot drift from the code (tests/docs/test_cli_reference.py fails when it does). After changing a verb
or an option, rewrite it with::

    python -m rfr_viz.cli.reference          # docs/cli.md, or the page named
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

import typer
from rich.text import Text

from rfr_viz.cli.app import app
from robofailring.atomic import write_text_atomic
from robofailring.errors import SettingError

#: The lines of docs/cli.md between which the generated reference stands.
BEGIN: Final = "<!-- cli-reference: written by `python -m rfr_viz.cli.reference`; edit the code, not this -->"
END: Final = "<!-- /cli-reference -->"
#: The command that rewrites the committed reference, as the stale-page test names it.
REGENERATE: Final = "python -m rfr_viz.cli.reference"
#: The page it is written into, from the checkout's root.
PAGE: Final = Path("docs/cli.md")
# typer's own panel names, for the parameters no option group places
_ARGUMENTS: Final = "Arguments"
_OPTIONS: Final = "Options"


def verbs() -> dict[str, Any]:
    """Every verb of the `robofailring` command by name (typer's click commands), as `--help` lists them."""
    group: Any = typer.main.get_command(app)
    context = typer.Context(group, info_name="robofailring")
    return {name: group.get_command(context, name) for name in group.list_commands(context)}


def _line(text: str) -> str:
    """Help text as one line, as `--help` shows it: Rich markup read (`\\[` is a bracket), spaces folded."""
    return " ".join(Text.from_markup(text).plain.split())


def _item(param: Any, context: typer.Context) -> str | None:
    """One argument or option as a list item: its name and metavar, then its help and its default."""
    record = param.get_help_record(context)
    if record is None:
        return None
    own = param.help or ""
    extra = record[1][len(own) :] if record[1].startswith(own) else record[1]  # `[default: …]`, `[required]`
    said = " ".join(part for part in (_line(own), " ".join(extra.split())) if part)
    return f"- `{' '.join(record[0].split())}`: {said}"


def panels(command: Any, context: typer.Context) -> dict[str, list[Any]]:
    """A verb's arguments and options by the panel `--help` lists them under, in its order: the arguments,
    the verb's own options, then each option group's."""
    found: dict[str, list[Any]] = {_ARGUMENTS: [], _OPTIONS: []}
    for param in command.get_params(context):
        if param.name == "help":
            continue
        default = _ARGUMENTS if param.param_type_name == "argument" else _OPTIONS
        found.setdefault(getattr(param, "rich_help_panel", None) or default, []).append(param)
    return {panel: params for panel, params in found.items() if params}


def verb_reference(name: str, command: Any, *, level: int = 3) -> str:
    """One verb: its help, its usage line, and its arguments and options with their help, by panel."""
    context = typer.Context(command, info_name=f"robofailring {name}")
    params = command.get_params(context)
    arguments = " ".join((p.name or "").upper() for p in params if p.param_type_name == "argument")
    lines = [f"{'#' * level} `{name}`", "", _line(command.help or ""), ""]
    lines += ["```", f"robofailring {name} [OPTIONS] {arguments}".rstrip(), "```", ""]
    for panel, members in panels(command, context).items():
        items = [item for item in (_item(param, context) for param in members) if item is not None]
        if items:
            lines += [f"**{panel}**", "", *items, ""]
    return "\n".join(lines)


def cli_reference(*, level: int = 3) -> str:
    """Every verb's reference, in `--help`'s order."""
    return "\n".join(verb_reference(name, command, level=level) for name, command in verbs().items())


def with_reference(page: str) -> str:
    """`page` (docs/cli.md's text) with the reference between its `BEGIN` and `END` lines written anew."""
    head, begin, rest = page.partition(BEGIN + "\n")
    _, end, tail = rest.partition(END + "\n")
    if not begin or not end:
        raise SettingError(f"the page has no {BEGIN!r} … {END!r} lines for the command-line reference")
    return f"{head}{BEGIN}\n\n{cli_reference(level=3)}\n{END}\n{tail}"


def main(argv: Sequence[str] | None = None) -> int:
    """Rewrite the reference in the page named (default docs/cli.md); print what was written."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) > 1 or any(arg.startswith("-") for arg in args):
        print(f"usage: {REGENERATE} [PAGE]  (default {PAGE}: its command-line reference rewritten)")
        return 0 if args in (["-h"], ["--help"]) else 2
    page = Path(args[0]) if args else PAGE
    if not page.is_file():
        print(
            f"error: {page}: no such page (run from the checkout's root, or name the page)", file=sys.stderr
        )
        return 2
    old = page.read_text(encoding="utf-8")
    try:
        new = with_reference(old)
    except SettingError as error:
        print(f"error: {page}: {error}", file=sys.stderr)
        return 2
    if new != old:
        write_text_atomic(page, new)
    print(f"{page}: command-line reference {'rewritten' if new != old else 'already current'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
