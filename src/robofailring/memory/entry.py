"""One failure memory entry (a view of a failure trajectory) and one retrieved neighbour of a query."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from robofailring.data.grounding import Vocabulary, ground


@dataclass(frozen=True)
class MemoryEntry:
    """Grounded metadata of one memory vector (one view of one failure trajectory).

    `start` and `end` are absolute image paths in a loaded or built memory; on disk they are
    stored relative to the memory's data root (`robofailring.memory.references`). `vocabulary` is
    the memory's own (its symbols beyond Table 5), given by the memory that holds the entry.
    """

    task: str
    symbol: str
    episode: str
    view: str
    start: str
    end: str
    written: str | None = None  # the label's own description of this failure, stored as `description`
    vocabulary: Vocabulary | None = field(default=None, compare=False, repr=False)

    @property
    def description(self) -> str:
        """The grounded sentence: the label's own description, else G(symbol) with the memory's vocabulary."""
        return self.written if self.written else ground(self.symbol, self.vocabulary)

    def to_dict(self) -> dict[str, Any]:
        """The entry as `entries.jsonl` stores it (`description` only when the label wrote one)."""
        stored: dict[str, Any] = {
            "task": self.task,
            "symbol": self.symbol,
            "episode": self.episode,
            "view": self.view,
            "start": self.start,
            "end": self.end,
        }
        return stored | ({"description": self.written} if self.written else {})


@dataclass(frozen=True)
class Neighbor:
    """One retrieved memory entry with its cosine similarity to the query."""

    index: int
    similarity: float
    entry: MemoryEntry

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "similarity": round(self.similarity, 6), **self.entry.to_dict()}
