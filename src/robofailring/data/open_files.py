"""A bound on the readers a layout keeps open (video containers, bags): the least recently opened closes."""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Generic, Protocol, TypeVar


class Closable(Protocol):
    def close(self) -> None: ...


Reader = TypeVar("Reader", bound=Closable)


class OpenLimit(Generic[Reader]):
    """At most `limit` readers open at once; remembering one more closes the least recently opened."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self._open: OrderedDict[int, Reader] = OrderedDict()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._open)

    def remember(self, reader: Reader) -> None:
        """`reader` has just opened its file."""
        with self._lock:
            self._open[id(reader)] = reader
            self._open.move_to_end(id(reader))
            while len(self._open) > self.limit:
                _, oldest = self._open.popitem(last=False)
                if oldest is not reader:
                    oldest.close()
