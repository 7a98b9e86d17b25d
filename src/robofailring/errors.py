"""The project's exception types: every user-facing error names the file or value at fault."""

from __future__ import annotations

import errno


class RoboFailRingError(Exception):
    """Base class of every error the library raises on purpose.

    `exit_code` is the command line's exit status for it (see `robofailring.cli.exit_codes`): 2, bad
    usage or input, unless the class says otherwise.
    """

    exit_code: int = 2


class DataError(RoboFailRingError):
    """A dataset, trajectory or image could not be read or does not match a known layout."""


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


class MissingExtraError(RoboFailRingError, ModuleNotFoundError):
    """A module of an optional part of the install is not installed; the message names the extra.

    An error of the environment (exit status 1); still a `ModuleNotFoundError`, for code that probes
    for optional modules (`robofailring.extras.needs_extra` raises it).
    """

    exit_code = 1

    def __init__(self, message: str, *, name: str, extra: str) -> None:
        super().__init__(message, name=name)
        self.extra = extra


def describe(error: BaseException) -> str:
    """One sentence for an error: an OSError names the file and what went wrong, without errno noise."""
    if not isinstance(error, OSError) or error.strerror is None:
        return str(error)
    where = f" {error.filename}" if error.filename is not None else ""
    if error.filename2 is not None:
        where += f" -> {error.filename2}"
    if error.errno == errno.ENOSPC:
        return f"no space left on the device while writing{where}; free some space and run again"
    if error.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return f"cannot write{where}: {error.strerror.lower()}; choose a folder you can write to"
    return f"{error.strerror}:{where}" if where else error.strerror
