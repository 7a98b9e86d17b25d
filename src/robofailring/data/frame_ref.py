"""A frame's reference: the one parse and the one read of where a memory's, a report's or a recording's image lies.

A reference is text, as memories store it (`docs/architecture.md`, "Memory folder"), in one of five forms:

- `<array>`: a frame held in memory (no file behind it);
- `<file>`: an image file;
- `<video>#frame=<i>`: frame i of a video file;
- `<file>#/<dataset>#frame=<i>`: row i of an HDF5 image dataset;
- `<bag>#topic=<topic>&message=<i>`: message i of a ROS bag's image topic (a ROS 2 bag is a folder).

`FrameRef.parse` reads the text once into a typed value, and the modules that own a container (`video.py`,
`hdf5.py`, the ROS bag layout) make their frames' references with `FrameRef.video`, `.hdf5` and `.bag` and
register how to read one (`register_reader`); `read_frame` and `reference_jpeg` are the one read, for the
memory, the VLM and the recordings alike.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Final

import numpy as np

from robofailring.data.images import encode_jpeg, is_jpeg, read_image
from robofailring.errors import DataError

ARRAY_REFERENCE: Final[str] = "<array>"  # a frame with no file behind it
_FRAME: Final[str] = "#frame="  # a video frame's or an HDF5 row's index follows
_DATASET: Final[str] = "#/"  # an HDF5 dataset's path follows the file
_TOPIC: Final[str] = "#topic="  # a bag image topic follows the bag
_MESSAGE: Final[str] = "&message="  # the topic's message number follows


class Container(StrEnum):
    """A file that holds many frames; the value names one of its frames in messages."""

    VIDEO = "video frame"
    HDF5 = "HDF5 image row"
    BAG = "ROS bag message"


@dataclass(frozen=True)
class FrameRef:
    """Where one frame lies: `file` (a bag: its file or folder), and inside it, for a container, the HDF5
    dataset or bag topic (`inner`) and the frame's number (`index`, None when the text gives none)."""

    text: str  # the reference as written, stored and shown
    file: str
    container: Container | None = None  # None: `file` is the image (or the frame is in memory)
    inner: str = ""
    index: int | None = None

    @classmethod
    def parse(cls, text: str) -> FrameRef:
        """The reference `text` means (any text parses: one that is none of the forms is a file)."""
        if not text.startswith("<"):
            bag, topic_marker, rest = text.partition(_TOPIC)
            if topic_marker:
                topic, message_marker, index = rest.rpartition(_MESSAGE)
                return cls(text, bag, Container.BAG, topic, _number(index) if message_marker else None)
            head, frame_marker, index = text.rpartition(_FRAME)
            if frame_marker:
                file, dataset_marker, dataset = head.partition(_DATASET)
                if dataset_marker:
                    return cls(text, file, Container.HDF5, "/" + dataset, _number(index))
                return cls(text, head, Container.VIDEO, "", _number(index))
        return cls(text, text)

    @classmethod
    def video(cls, file: Path | str, index: int) -> FrameRef:
        """Frame `index` of a video file."""
        return cls(f"{file}{_FRAME}{index}", str(file), Container.VIDEO, "", index)

    @classmethod
    def hdf5(cls, file: Path | str, dataset: str, index: int) -> FrameRef:
        """Row `index` of the image dataset `dataset` (a path from the file's root, `/data/demo_0/obs/x`)."""
        return cls(f"{file}#{dataset}{_FRAME}{index}", str(file), Container.HDF5, dataset, index)

    @classmethod
    def bag(cls, bag: Path | str, topic: str, index: int) -> FrameRef:
        """Message `index` of a bag's image topic `topic`."""
        return cls(f"{bag}{_TOPIC}{topic}{_MESSAGE}{index}", str(bag), Container.BAG, topic, index)

    @property
    def is_file(self) -> bool:
        """False for a frame held in memory (`<array>`), which has no file behind it."""
        return not self.text.startswith("<")

    @property
    def fragment(self) -> str:
        """What follows the file: a container frame's place in it (`#frame=3`), else nothing."""
        return self.text[len(self.file) :]

    def moved(self, file: Path | str) -> FrameRef:
        """The same frame in `file` (its dataset moved)."""
        return FrameRef.parse(f"{file}{self.fragment}")

    def __str__(self) -> str:
        return self.text


def _number(text: str) -> int | None:
    return int(text) if text.isdecimal() else None


FrameReader = Callable[[FrameRef], "np.ndarray | None"]
_READERS: dict[Container, FrameReader] = {}


def register_reader(container: Container, reader: FrameReader) -> None:
    """How the frames of `container` are read (its module calls this once, at import): the image, or None
    when the reference's file, dataset or topic is not there."""
    _READERS[container] = reader


def read_frame(reference: FrameRef | str) -> np.ndarray | None:
    """The RGB image a container frame's reference points at, or None when it is not there (or not one)."""
    ref = reference if isinstance(reference, FrameRef) else FrameRef.parse(reference)
    if ref.container is None or ref.index is None:
        return None
    return _READERS[ref.container](ref)


def reference_jpeg(
    reference: FrameRef | str, *, quality: int, what: str = "image", needed: str = ""
) -> bytes:
    """The frame a reference names as JPEG bytes (a JPEG file passes through unchanged); DataError naming it
    (as `what`, with `needed` after: why it was wanted) when it is not there or cannot be read."""
    ref = reference if isinstance(reference, FrameRef) else FrameRef.parse(reference)
    if ref.container is not None:
        image = read_frame(ref)
        if image is None:
            raise DataError(f"{what} {ref} is not a readable {ref.container}{needed}")
        return encode_jpeg(image, quality=quality)
    path = Path(ref.file)
    if not ref.is_file or not path.is_file():
        raise DataError(f"{what} {ref} is not a readable file{needed}")
    try:
        data = path.read_bytes()
    except OSError as error:
        raise DataError(f"cannot read {what} {ref}: {error.strerror or error}") from error
    return data if is_jpeg(data) else encode_jpeg(read_image(path), quality=quality)
