"""The command line's exit statuses, and the one place that turns an error into a sentence and a status.

0 done; 1 an error of the environment (no permission, disk full, output busy); 2 bad usage or
input (a file, folder or value named in the message); 3 done, but some inputs were skipped (the
summary of what was skipped is printed before exiting); 130 interrupted (Ctrl-C, SIGINT: 128 + 2,
as a shell reports it), whether the verb was running or the command was still loading; 143 stopped by
SIGTERM (128 + 15: a scheduler's or `kill`'s stop), after the verb let go of its locks and temporary files.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType
from typing import Any, Final, NoReturn

import typer
from typer import _click
from typer.core import TyperGroup

from robofailring.errors import RoboFailRingError, Terminated, describe

DONE: Final[int] = 0
ERROR: Final[int] = 1
BAD_INPUT: Final[int] = 2
SKIPPED: Final[int] = 3
INTERRUPTED: Final[int] = 130
TERMINATED: Final[int] = 143


def _terminate(signum: int, frame: FrameType | None) -> None:
    raise Terminated


def exit_code_for(error: BaseException) -> int:
    """The exit status an error ends the command with."""
    if isinstance(error, RoboFailRingError):
        return error.exit_code
    if isinstance(error, (FileNotFoundError, NotADirectoryError, IsADirectoryError, ValueError)):
        return BAD_INPUT
    return ERROR


def fail(error: BaseException) -> NoReturn:
    """Print `error: <sentence>` on stderr and end the command with the error's exit status."""
    typer.secho(f"error: {describe(error)}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code=exit_code_for(error))


def interrupted() -> int:
    """Say `error: interrupted` on stderr (Ctrl-C); the exit status to end with, for the caller to raise."""
    typer.secho("error: interrupted (Ctrl-C)", fg=typer.colors.RED, err=True)
    return INTERRUPTED


def finish(*, skipped: int = 0, failure: RoboFailRingError | None = None) -> None:
    """End a command once its summary is printed: `failure` (a job's result says its work failed) is
    raised for `ErrorMappingGroup` to print and map; else status 3 when some inputs were skipped."""
    if failure is not None:
        raise failure
    if skipped:
        raise typer.Exit(code=SKIPPED)


class ErrorMappingGroup(TyperGroup):
    """A typer command group whose verbs end in one line and an exit status instead of a traceback.

    Errors the library raises on purpose (`RoboFailRingError`: a bad setting is a `SettingError`)
    and operating-system errors (permission, disk full, a file where a folder belongs) are caught
    here, for every verb; no verb catches errors of its own. A Ctrl-C is one line and status 130,
    whenever it comes (`main`; `rfr_viz.cli.app` says the same for one while the verbs load).
    """

    _said_interrupted = False  # this run's Ctrl-C said already

    def main(self, *args: Any, **kwargs: Any) -> Any:
        """The command run whole: a Ctrl-C at any moment of it is one line and 130 (typer ends one that
        comes while it parses the arguments in a bare 130, and one outside its own `try` in a traceback)."""
        self._said_interrupted = False
        try:
            return super().main(*args, **kwargs)
        except KeyboardInterrupt:
            raise SystemExit(self._interrupted()) from None
        except SystemExit as end:
            if end.code == INTERRUPTED and not self._said_interrupted:
                self._interrupted()
            raise

    def _interrupted(self) -> int:
        self._said_interrupted = True
        return interrupted()

    def invoke(self, ctx: _click.Context) -> Any:
        main = threading.current_thread() is threading.main_thread()  # only it may handle signals
        previous = None
        try:
            previous = signal.signal(signal.SIGTERM, _terminate) if main else None
            return super().invoke(ctx)
        except (RoboFailRingError, OSError) as error:
            fail(error)
        except KeyboardInterrupt:
            raise typer.Exit(code=self._interrupted()) from None
        except Terminated:
            typer.secho("error: terminated (SIGTERM)", fg=typer.colors.RED, err=True)
            raise typer.Exit(code=TERMINATED) from None
        finally:
            if main and previous is not None:
                signal.signal(signal.SIGTERM, previous)
