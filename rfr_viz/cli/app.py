"""The one `robofailring` command: the library's verbs and the recording verbs, composed here.

Each group of verbs is its own typer app (typer's "one file per command"); nobody registers verbs on
another module's app. Options shared by several verbs are declared once, in
`robofailring.cli.options`. Errors become one sentence and an exit status (`robofailring.cli.exit_codes`).

Loading the verbs (numpy, OpenCV, Faiss, typer) takes most of a second and happens here, the first
of the command's own code to run (`import robofailring` and `import rfr_viz` load none of it): a
Ctrl-C meanwhile ends as one while a verb runs does, one `error:` line and status 130.
"""

from __future__ import annotations

try:
    import typer

    from rfr_viz.cli.jobs import app as jobs_app
    from rfr_viz.cli.live import app as live_app
    from rfr_viz.cli.replay import app as replay_app
    from robofailring.cli.exit_codes import ErrorMappingGroup
    from robofailring.cli.verbs import app as library_app
except KeyboardInterrupt:
    from robofailring.cli.exit_codes import interrupted

    raise SystemExit(interrupted()) from None

__all__ = ["app", "main"]

app = typer.Typer(
    name="robofailring",
    help="Retrieval-based robot failure detection (RoboFailRing) and its Rerun recordings.",
    cls=ErrorMappingGroup,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
for verbs in (library_app, replay_app, jobs_app, live_app):
    app.add_typer(verbs)


def main() -> None:
    """Console entry point (`robofailring`)."""
    app()


if __name__ == "__main__":
    main()
