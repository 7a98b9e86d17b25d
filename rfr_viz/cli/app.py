"""The one `robofailring` command: the library's verbs and the recording verbs, composed here.

Each group of verbs is its own typer app (typer's "one file per command"); nobody registers verbs on
another module's app. Options shared by several verbs are declared once, in
`robofailring.cli.options`, and the options that make one value once, as its option group
(`robofailring.cli.option_groups`). Errors become one sentence and an exit status (`robofailring.cli.exit_codes`).

Loading the verbs (numpy, OpenCV, Faiss, typer) takes most of a second and happens here, the first
of the command's own code to run (`import robofailring` and `import rfr_viz` load none of it): a
Ctrl-C at any point after the console script's first line (the imports, the app built, typer building
the command, the arguments parsed, the verb run) ends as one while a verb runs does, one `error:` line
and status 130 (tests/cli/test_interrupts.py sends one at many moments of the first 0.4 s).

The command speaks for itself: its own warnings (the `robofailring` logger, `warning: …`) and one
`error:` line. What the libraries beneath it log on their own (open_clip's `ERROR:root:` before the
error that explains it, Rerun's and OpenCV's `WARN` lines) is not printed unless asked for with
`ROBOFAILRING_LOG=all` (`RUST_LOG` and `OPENCV_LOG_LEVEL`, when set, are left as they are).
"""

from __future__ import annotations

import atexit
import signal
import sys  # these three are built into the interpreter: nothing before the `try` takes time

_late_ctrl_c: list[bool] = []  # a Ctrl-C after the command ended (while the interpreter exits)
_ended_interrupted: list[bool] = []  # the command itself ended by a Ctrl-C, and said so


def _note_late_ctrl_c(signum: int, frame: object) -> None:
    """A Ctrl-C once the command has ended: noted (said by `_end_as_interrupted`), never a traceback."""
    _late_ctrl_c.append(True)


def _end_as_interrupted() -> None:
    """The last thing before the interpreter's finalization (registered first, it runs last): SIGINT
    ignored from here (finalization would put back the default and the process would die of a late
    Ctrl-C without a word), and a late Ctrl-C said as one line and status 130."""
    if signal.getsignal(signal.SIGINT) is _note_late_ctrl_c:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    if _late_ctrl_c:
        if not _ended_interrupted:
            interrupted()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(INTERRUPTED)


atexit.register(_end_as_interrupted)

try:  # everything the command loads, so that a Ctrl-C meanwhile ends as one while a verb runs does
    import logging
    import os
    import threading

    if os.environ.get("ROBOFAILRING_LOG") != "all":  # before Rerun and OpenCV load and read them
        os.environ.setdefault("RUST_LOG", "error")
        os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

    import typer

    from rfr_viz.cli.jobs import app as jobs_app
    from rfr_viz.cli.live import app as live_app
    from rfr_viz.cli.replay import app as replay_app
    from rfr_viz.cli.triage import app as triage_app
    from robofailring.cli.exit_codes import INTERRUPTED, ErrorMappingGroup, interrupted
    from robofailring.cli.verbs import app as library_app

    app = typer.Typer(
        name="robofailring",
        help="Retrieval-based robot failure detection (RoboFailRing) and its Rerun recordings.",
        cls=ErrorMappingGroup,
        no_args_is_help=True,
        pretty_exceptions_enable=False,
        add_completion=False,
    )
    for verbs in (library_app, replay_app, jobs_app, triage_app, live_app):
        app.add_typer(verbs)
except KeyboardInterrupt:
    from robofailring.cli.exit_codes import interrupted

    raise SystemExit(interrupted()) from None

__all__ = ["app", "main"]


class _OwnRecords(logging.Filter):
    """The command's own log records only (the `robofailring` logger and its children)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return record.name == "robofailring" or record.name.startswith("robofailring.")


def _log_to_stderr() -> None:
    """The command's warnings on stderr as their message alone; other loggers' records dropped, unless
    `ROBOFAILRING_LOG=all` (a root handler also keeps `logging.error()` from configuring its own)."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s"))
    if os.environ.get("ROBOFAILRING_LOG") != "all":
        handler.addFilter(_OwnRecords())
    root = logging.getLogger()
    root.addHandler(handler)
    root.setLevel(logging.WARNING)


def main() -> None:
    """Console entry point (`robofailring`): a Ctrl-C while typer builds the command from its verb apps is
    one line and 130 too (while it parses or runs a verb, `ErrorMappingGroup` says it), and so is one
    after the command ended, while the interpreter exits (`_end_as_interrupted`)."""
    try:
        _log_to_stderr()
        app()
    except KeyboardInterrupt:
        raise SystemExit(interrupted()) from None
    except SystemExit as end:
        if end.code == INTERRUPTED:
            _ended_interrupted.append(True)
        raise
    finally:  # all output printed: a Ctrl-C from here on is noted, and said as the interpreter exits
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, _note_late_ctrl_c)


if __name__ == "__main__":
    main()
