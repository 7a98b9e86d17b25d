"""One failure memory entry (a view of a failure trajectory) and one retrieved neighbour of a query."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from robofailring.data.grounding import ground


@dataclass(frozen=True)
class MemoryEntry:
    """Grounded metadata of one memory vector (one view of one failure trajectory).

    `start` and `end` are absolute image paths in a loaded or built memory; on disk they are
    stored relative to the memory's data root (`robofailring.memory.references`).
    """

    task: str
    symbol: str
    episode: str
    view: str
    start: str
    end: str

    @property
    def description(self) -> str:
        """G(symbol), the grounded sentence."""
        return ground(self.symbol)


@dataclass(frozen=True)
class Neighbor:
    """One retrieved memory entry with its cosine similarity to the query."""

    index: int
    similarity: float
    entry: MemoryEntry

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "similarity": round(self.similarity, 6), **asdict(self.entry)}
