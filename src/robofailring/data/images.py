"""Reading, hashing and resizing RGB images; every failure names the file."""

from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np

from robofailring.errors import DataError, read_error

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".webp")


def decode_image(data: bytes, *, source: str, stored_rgb: bool = False) -> np.ndarray:
    """Decode encoded image bytes to an (H, W, 3) uint8 RGB array; a 16-bit image is an error.

    `stored_rgb`: the encoder was given an RGB array as it was (ALOHA's `cv2.imencode` on the camera's
    RGB frame), so the channels decode as RGB already and are not swapped.
    """
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
    if array.shape[2] == 4:
        array = array[:, :, :3]
    if array.dtype != np.uint8:
        if np.issubdtype(array.dtype, np.floating) and array.size and float(array.max()) <= 1.0:
            array = array * 255.0
        array = np.clip(array, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(array)


def content_digest(data: bytes) -> str:
    """A short, stable digest of image content, used as the embedding-cache key."""
    return hashlib.blake2b(data, digest_size=16).hexdigest()


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
