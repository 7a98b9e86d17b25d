"""One failure memory entry (a view of a failure trajectory at one moment) and one retrieved neighbour of a
query; which moments a memory holds (`end`, the paper's, or `dense`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Final

from robofailring.data.grounding import Vocabulary, ground
from robofailring.errors import SettingError

END: Final[str] = "end"  # the paper's memory: one (I_0 ‖ I_end) entry per failure view
DENSE: Final[str] = "dense"  # also (I_0 ‖ I_τ) for the frames from the failure's onset on, thinned
FAILURE_FRAMES: Final[tuple[str, ...]] = (END, DENSE)


def check_failure_frames(value: str) -> str:
    """`end` or `dense`, the frames of a failure run the memory holds (SettingError naming both otherwise)."""
    if value not in FAILURE_FRAMES:
        raise SettingError(f"failure frames must be {' or '.join(FAILURE_FRAMES)}, got {value!r}")
    return value


def moment_text(frame: int | None, length: int | None) -> str:
    """A moment of a failure run: "frame 34 of 40 (85 %)", "frame 39 of 40 (end of the run)", or "end of
    the run" when the frame is not known (the paper's entry)."""
    if frame is None or length is None:
        return "end of the run"
    if frame == length - 1:
        return f"frame {frame} of {length} (end of the run)"
    return f"frame {frame} of {length} ({round(100 * frame / length)} %)"


def failure_frames_note(failure_frames: str) -> str:
    """What a memory of `failure_frames` holds, in a few words (for tables and notes)."""
    if failure_frames == DENSE:
        return "dense: each failure run's frames from its onset on, thinned; `--failure-frames end` gives the paper's"
    return "end: the paper's memory, one (I_0 ‖ I_end) entry per failure view"


@dataclass(frozen=True)
class MemoryEntry:
    """Grounded metadata of one memory vector: one view of one failure trajectory, paired from its first
    frame to its last (`frame` None) or, in a dense memory, to its frame `frame`.

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
    frame: int | None = None  # τ, the run's frame `end` is (None: its last frame, the paper's entry)
    length: int | None = None  # frames in this view of the run (None with `frame`)
    vocabulary: Vocabulary | None = field(default=None, compare=False, repr=False)

    @property
    def description(self) -> str:
        """The grounded sentence: the label's own description, else G(symbol) with the memory's vocabulary."""
        return self.written if self.written else ground(self.symbol, self.vocabulary)

    @property
    def moment(self) -> str:
        """Which moment of its run the entry's `end` image is (`moment_text`)."""
        return moment_text(self.frame, self.length)

    def to_dict(self) -> dict[str, Any]:
        """The entry as `entries.jsonl` stores it (`description` only when the label wrote one, `frame` and
        `length` only when set)."""
        stored: dict[str, Any] = {
            "task": self.task,
            "symbol": self.symbol,
            "episode": self.episode,
            "view": self.view,
            "start": self.start,
            "end": self.end,
        }
        if self.written:
            stored["description"] = self.written
        if self.frame is not None and self.length is not None:
            stored |= {"frame": self.frame, "length": self.length}
        return stored


@dataclass(frozen=True)
class Neighbor:
    """One retrieved memory entry with its cosine similarity to the query."""

    index: int
    similarity: float
    entry: MemoryEntry

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "similarity": round(self.similarity, 6), **self.entry.to_dict()}
