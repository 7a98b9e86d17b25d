"""JPEG bytes for the recording: source JPEGs pass through, anything else is encoded once."""

from __future__ import annotations

from typing import Final

import cv2

from robofailring.data.frame_ref import reference_jpeg as frame_reference_jpeg
from robofailring.data.images import encode_jpeg, is_jpeg
from robofailring.data.model import Frame
from robofailring.errors import DataError
from robofailring.memory.image_roots import ImageRoots

JPEG_QUALITY: Final[int] = 80
JPEG_MEDIA_TYPE: Final[str] = "image/jpeg"


def frame_jpeg(frame: Frame, *, quality: int = JPEG_QUALITY) -> bytes:
    """The frame as JPEG bytes: the file itself when it already is a JPEG."""
    data = frame.read_bytes()
    if data is not None and is_jpeg(data):
        return data
    return encode_jpeg(frame.load(), quality=quality)


def reference_jpeg(reference: str, roots: ImageRoots, *, quality: int = JPEG_QUALITY) -> bytes | None:
    """JPEG bytes of a memory entry's start/end image, or None when the file is not there or lies outside
    `roots` (the folders named for the memory's images: an edited memory must not record your files)."""
    if not roots.holds(reference):
        return None
    try:
        return frame_reference_jpeg(reference, quality=quality)
    except (OSError, DataError):
        return None  # a memory image that went missing must not sink the whole recording


class ReferenceJpegs:
    """A recording's memory images as JPEG bytes, each read once, and only from under `roots`."""

    def __init__(self, roots: ImageRoots) -> None:
        self.roots = roots
        self._jpegs: dict[str, bytes | None] = {}

    def get(self, reference: str) -> bytes | None:
        """The image's JPEG bytes; None when it is missing or outside the roots (`absence` says which)."""
        if reference not in self._jpegs:
            self._jpegs[reference] = reference_jpeg(reference, self.roots)
        return self._jpegs[reference]

    def looked_for_in_vain(self, reference: str) -> bool:
        """Whether the image was asked for and is not shown."""
        return reference in self._jpegs and self._jpegs[reference] is None

    def absence(self, reference: str) -> str:
        """Markdown naming an image that is not shown, and why."""
        if not self.roots.holds(reference):
            return f"**image not read** (outside the folders named for it: {self.roots}): `{reference}`"
        return f"**image not found:** `{reference}`"


def thumbnail_jpeg(frame: Frame, *, side: int = 128, quality: int = JPEG_QUALITY) -> bytes:
    """The frame shrunk to at most `side` pixels a side, as JPEG bytes (a triage thumbnail)."""
    image = frame.load()
    scale = side / max(image.shape[:2])
    if scale < 1:
        size = (max(1, round(image.shape[1] * scale)), max(1, round(image.shape[0] * scale)))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return encode_jpeg(image, quality=quality)
