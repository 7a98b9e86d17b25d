"""Progress for long work on stderr: a bar on a terminal (or in a notebook), plain lines in a log.

A bar redraws itself with `\r`, which a log file or a CI console keeps as one ever-growing line; where
stderr is not a terminal, progress is instead one line at most every `LOG_EVERY_S` seconds and one at
the end. `ROBOFAILRING_PROGRESS=0` silences it, `ROBOFAILRING_PROGRESS=1` draws the bar anyway.
"""

from __future__ import annotations

import os
import sys
import time
from types import TracebackType
from typing import Any, Final, TextIO

from tqdm.auto import tqdm

LOG_EVERY_S: Final[float] = 30.0  # at most one progress line per this many seconds where it is logged


class LineProgress:
    """Progress as whole lines (`triage: 120/400 episode (30 %)`), never `\\r`: for a log, not a terminal."""

    def __init__(self, *, total: int | None, desc: str, unit: str, stream: TextIO | None = None) -> None:
        self.total, self.desc, self.unit = total, desc, unit
        self.stream = stream if stream is not None else sys.stderr
        self.n = 0
        self._said = time.monotonic()

    def update(self, n: int = 1) -> None:
        self.n += n
        if time.monotonic() - self._said >= LOG_EVERY_S:
            self._say()

    def close(self) -> None:
        if self.n:
            self._say()

    def _say(self) -> None:
        share = f" ({100 * self.n / self.total:.0f} %)" if self.total else ""
        of = f"/{self.total:,}" if self.total is not None else ""
        print(f"{self.desc}: {self.n:,}{of} {self.unit}{share}", file=self.stream, flush=True)
        self._said = time.monotonic()

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.close()


def _drawn() -> bool:
    """Whether a bar can be drawn: stderr is a terminal, or a notebook shows tqdm's widget."""
    return sys.stderr.isatty() or "ipykernel" in sys.modules


def progress_bar(*, total: int | None, desc: str, unit: str = "it", disable: bool | None = None) -> Any:
    """Progress on stderr (module docstring): a tqdm bar, or `LineProgress` where stderr is not a terminal;
    `ROBOFAILRING_PROGRESS=0` silences it."""
    setting = os.environ.get("ROBOFAILRING_PROGRESS", "")
    if disable is None:
        disable = setting == "0"
    if not disable and setting != "1" and not _drawn():
        return LineProgress(total=total, desc=desc, unit=unit)
    return tqdm(total=total, desc=desc, unit=unit, disable=disable, dynamic_ncols=True, leave=False)
