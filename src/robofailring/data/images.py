"""Reading, hashing and resizing RGB images; every failure names the file.

A frame larger than `max_frame_pixels()` (width × height; 50 megapixels unless
`ROBOFAILRING_MAX_FRAME_PIXELS` says otherwise) is refused before it is decoded, by every decoder
(image files and encoded rows here, HDF5 arrays, videos, ROS bag images): a small file can declare
a huge frame (a PNG of 30000×30000 is 2.6 MB and decodes to 2.7 GB).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Final

import cv2
import numpy as np

from robofailring.errors import DataError, SettingError, read_error

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".webp")
MAX_FRAME_PIXELS: Final[int] = (
    50_000_000  # per frame, width × height, unless the setting below says otherwise
)
MAX_FRAME_PIXELS_SETTING: Final[str] = "ROBOFAILRING_MAX_FRAME_PIXELS"
_JPEG_MAGIC: Final[bytes] = b"\xff\xd8\xff"
_JPEG_FRAME_MARKERS: Final[frozenset[int]] = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}  # SOF0–SOF15


def max_frame_pixels() -> int:
    """The most pixels (width × height) one frame may have: `$ROBOFAILRING_MAX_FRAME_PIXELS` or 50 megapixels."""
    text = os.environ.get(MAX_FRAME_PIXELS_SETTING, "").strip()
    if not text:
        return MAX_FRAME_PIXELS
    try:
        limit = int(text)
    except ValueError:
        limit = 0
    if limit < 1:
        raise SettingError(
            f"{MAX_FRAME_PIXELS_SETTING} must be a whole number of pixels, at least 1, got {text!r}"
        )
    return limit


def check_frame_size(width: int, height: int, *, source: str) -> None:
    """DataError naming `source` and the setting when a frame of width × height is over `max_frame_pixels()`."""
    limit = max_frame_pixels()
    if width * height > limit:
        raise DataError(
            f"{source}: a frame of {width}×{height} pixels is larger than the {limit:,} pixels a frame may have; "
            f"if it is meant to be this large, set {MAX_FRAME_PIXELS_SETTING} to at least {width * height}"
        )


def encoded_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from a PNG, JPEG, BMP or WebP header, read without decoding; None for anything else."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR" and len(data) >= 24:
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if data[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    if data[:2] == b"BM" and len(data) >= 26:
        if int.from_bytes(data[14:18], "little") == 12:  # OS/2 BITMAPCOREHEADER: 16-bit sizes
            return int.from_bytes(data[18:20], "little"), int.from_bytes(data[20:22], "little")
        width = int.from_bytes(data[18:22], "little", signed=True)
        return abs(width), abs(int.from_bytes(data[22:26], "little", signed=True))  # negative: top-down
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP" and len(data) >= 30:
        chunk = data[12:16]
        if chunk == b"VP8 ":
            return int.from_bytes(data[26:28], "little") & 0x3FFF, int.from_bytes(
                data[28:30], "little"
            ) & 0x3FFF
        if chunk == b"VP8L":
            bits = int.from_bytes(data[21:25], "little")
            return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
        if chunk == b"VP8X":
            return int.from_bytes(data[24:27], "little") + 1, int.from_bytes(data[27:30], "little") + 1
    return None


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """The frame size of a JPEG's start-of-frame segment (the markers before it are skipped by length)."""
    position = 2
    while position + 9 <= len(data):
        if data[position] != 0xFF:
            return None
        marker = data[position + 1]
        if marker == 0xFF:  # fill byte
            position += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD8:  # markers without a length
            position += 2
            continue
        if marker in _JPEG_FRAME_MARKERS:
            height = int.from_bytes(data[position + 5 : position + 7], "big")
            return int.from_bytes(data[position + 7 : position + 9], "big"), height
        if marker in (0xD9, 0xDA):  # end of image, or scan data before any frame header
            return None
        position += 2 + int.from_bytes(data[position + 2 : position + 4], "big")
    return None


def decode_image(data: bytes, *, source: str, stored_rgb: bool = False) -> np.ndarray:
    """Decode encoded image bytes to an (H, W, 3) uint8 RGB array; a 16-bit image is an error.

    Only a PNG, JPEG, BMP or WebP whose header's frame size is within `max_frame_pixels()` is decoded.

    `stored_rgb`: the encoder was given an RGB array as it was (ALOHA's `cv2.imencode` on the camera's
    RGB frame), so the channels decode as RGB already and are not swapped.
    """
    size = encoded_size(data)
    if size is None:
        raise DataError(f"cannot decode image {source}: not a readable PNG/JPEG/BMP/WebP file")
    check_frame_size(*size, source=source)
    buffer = np.frombuffer(data, dtype=np.uint8)
    image = cv2.imdecode(buffer, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH) if buffer.size else None
    if image is None:
        raise DataError(f"cannot decode image {source}: not a readable PNG/JPEG/BMP/WebP file")
    if image.dtype != np.uint8:
        raise DataError(
            f"image {source} has {8 * image.itemsize}-bit samples (a depth map?), not an 8-bit colour image"
        )
    return np.ascontiguousarray(image if stored_rgb else image[:, :, ::-1])


def png_bit_depth(path: Path) -> int | None:
    """The bit depth a PNG file's header gives (8, 16, …), or None for a file that is not a PNG."""
    try:
        with Path(path).open("rb") as handle:
            head = handle.read(26)
    except OSError:
        return None
    if len(head) < 26 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return head[24]


def read_image(path: Path) -> np.ndarray:
    """Read an image file as (H, W, 3) uint8 RGB."""
    try:
        data = Path(path).read_bytes()
    except OSError as error:
        raise read_error(f"cannot read image {path}: {error.strerror or error}", error) from error
    return decode_image(data, source=str(path))


def as_rgb(image: np.ndarray, *, source: str = "image") -> np.ndarray:
    """Validate an in-memory image and return it as contiguous (H, W, 3) uint8 RGB."""
    array = np.asarray(image)
    if array.ndim == 2:
        array = np.repeat(array[:, :, None], 3, axis=2)
    if array.ndim != 3 or array.shape[2] not in (3, 4):
        raise DataError(f"{source}: expected an (H, W, 3) RGB image, got shape {array.shape}")
    if not array.shape[0] or not array.shape[1]:  # OpenCV asserts on an empty image when it is resized
        raise DataError(f"{source}: an image of shape {array.shape} is empty (no width or no height)")
    if array.shape[2] == 4:
        array = array[:, :, :3]
    if array.dtype != np.uint8:
        if np.issubdtype(array.dtype, np.floating):  # a NaN pixel is no light: black, as a dead sensor's
            array = np.nan_to_num(array, nan=0.0, posinf=255.0, neginf=0.0)
            if array.size and float(array.max()) <= 1.0:
                array = array * 255.0
        array = np.clip(array, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(array)


def content_digest(data: bytes) -> str:
    """A short, stable digest of image content, used as the embedding-cache key."""
    return hashlib.blake2b(data, digest_size=16).hexdigest()


def is_jpeg(data: bytes) -> bool:
    """Whether the bytes are a JPEG file (they pass through to a recording or a VLM as they are)."""
    return data[:3] == _JPEG_MAGIC


def encode_jpeg(image: np.ndarray, *, quality: int = 80) -> bytes:
    """JPEG-encode an RGB image."""
    ok, buffer = cv2.imencode(".jpg", image[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise DataError("JPEG encoding failed")
    return buffer.tobytes()


def write_png(path: Path, image: np.ndarray) -> None:
    """Write an RGB image as PNG (the caller handles atomicity of whole datasets)."""
    if not cv2.imwrite(str(path), image[:, :, ::-1]):
        raise DataError(f"cannot write image {path}")
