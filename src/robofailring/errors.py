"""The project's exception types: every user-facing error names the file or value at fault."""

from __future__ import annotations

import errno
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


class RoboFailRingError(Exception):
    """Base class of every error the library raises on purpose.

    `exit_code` is the command line's exit status for it (see `robofailring.cli.exit_codes`): 2, bad
    usage or input, unless the class says otherwise.
    """

    exit_code: int = 2


class DataError(RoboFailRingError):
    """A dataset, trajectory or image could not be read or does not match a known layout."""


class SplitError(DataError):
    """The data's train/test split cannot give a held-out evaluation (no test run, no training success to
    calibrate on, no test run of the memory's tasks); `evaluate --folds` still cross-validates over every
    labelled run, whatever its split."""


class RolloutError(RoboFailRingError):
    """A rollout under the monitor (`robofailring.monitor`) cannot be judged: a step before reset, an observation
    without a mapped camera, an image whose size changed mid-episode; the message names the step and the key."""


class SymbolError(RoboFailRingError):
    """A failure symbol has a token outside the grounding vocabulary (paper Table 5)."""


class VocabularyError(RoboFailRingError):
    """A vocabulary file (a dataset's own failure symbols) is unreadable, repeats a symbol or has an empty sentence."""


class EncoderError(RoboFailRingError):
    """An encoder spec is malformed or its weights are not available."""


class WeightsUnavailableError(EncoderError):
    """An encoder's pretrained weights are not on this machine and cannot be fetched: the environment's fault."""

    exit_code = 1


class MemoryFormatError(RoboFailRingError):
    """A failure-memory directory is missing, corrupt, or of another format version."""


class EncoderMismatchError(RoboFailRingError):
    """A memory is queried with an encoder other than the one that built it."""


class UnknownTaskError(RoboFailRingError):
    """A query names a task that has no entry in the memory."""


class SettingError(RoboFailRingError, ValueError):
    """A setting is outside its range (δ beyond [-1, 1], K below 1, a rate beyond [0, 1])."""


class OutputError(RoboFailRingError):
    """An output path is refused before any work: it is a file, the input, or a folder of other things."""


class OutputBusyError(RoboFailRingError):
    """Another robofailring process is writing the same output right now."""

    exit_code = 1


class WriteError(RoboFailRingError):
    """An output could not be written (no permission, disk full); nothing was half-written."""

    exit_code = 1


class ReadError(RoboFailRingError):
    """An input (a frame, a folder or file of the data) could not be read for lack of permission.

    An error of the environment (exit status 1), not of the input: the same data read by a user
    allowed to is fine. Other read faults (a file gone, bytes that do not decode) are `DataError`s.
    """

    exit_code = 1


class ClusterError(RoboFailRingError):
    """A compute cluster (Ray, `--ray ADDRESS`) could not be reached or failed; the message names its address.

    An error of the environment (exit status 1): the same command runs against a cluster that is up.
    """

    exit_code = 1


class MissingExtraError(RoboFailRingError, ModuleNotFoundError):
    """A module of an optional part of the install is not installed; the message names the extra.

    An error of the environment (exit status 1); still a `ModuleNotFoundError`, for code that probes
    for optional modules (`robofailring.extras.needs_extra` raises it).
    """

    exit_code = 1

    def __init__(self, message: str, *, name: str, extra: str) -> None:
        super().__init__(message, name=name)
        self.extra = extra


_NO_PERMISSION: tuple[int, ...] = (errno.EACCES, errno.EPERM)


def read_error(message: str, error: BaseException) -> RoboFailRingError:
    """The error to raise when reading an input failed with `error`: `message` as a `ReadError`
    (status 1) when permission was lacking, else as a `DataError` (status 2)."""
    if isinstance(error, OSError) and error.errno in _NO_PERMISSION:
        return ReadError(message)
    return DataError(message)


@contextmanager
def reading() -> Iterator[None]:
    """Reading a dataset: a `PermissionError` from the file system becomes a `ReadError` naming the
    file or folder that could not be read (a folder whose entries cannot be looked up, not a file in it)."""
    try:
        yield
    except PermissionError as error:
        if error.filename is None:
            raise ReadError(f"cannot read the data: {error.strerror or error}") from error
        path = Path(os.fsdecode(error.filename))
        folder = path.parent
        if not os.access(folder, os.R_OK | os.X_OK):  # its folder cannot be listed or entered
            path = folder
        kind = "folder " if os.path.isdir(path) else ""
        raise ReadError(
            f"cannot read {kind}{path}: permission denied; give this user read access to it"
        ) from error


def describe(error: BaseException) -> str:
    """One sentence for an error: an OSError names the file and what went wrong, without errno noise."""
    if not isinstance(error, OSError) or error.strerror is None:
        return str(error)
    where = f" {error.filename}" if error.filename is not None else ""
    if error.filename2 is not None:
        where += f" -> {error.filename2}"
    if error.errno == errno.ENOSPC:
        return f"no space left on the device while writing{where}; free some space and run again"
    if error.errno == errno.EROFS:
        return f"cannot write{where}: {error.strerror.lower()}; choose a folder you can write to"
    if error.errno in (errno.EACCES, errno.EPERM):  # reading or writing: the error does not say which
        return f"no permission to use{where}; give this user access to it, or choose another path"
    return f"{error.strerror}:{where}" if where else error.strerror


class BlindCameraWarning(UserWarning):
    """A live session's camera view sees nothing (a black, single-colour or not-a-number frame): it is not
    scored, so its `alarm=False` says nothing about the robot. Warned once per view and session; every
    step lists such views in `StepResult.blind_views` (`warnings.simplefilter("error", BlindCameraWarning)`
    turns it into an exception)."""


class Terminated(BaseException):
    """SIGTERM while a verb runs (`robofailring.cli.exit_codes`): raised where the verb is, so that every
    `with` block on the way out releases its lock and removes its temporary files (not an Exception:
    nothing swallows it), and a live recording keeps what it recorded, as a Ctrl-C does."""
