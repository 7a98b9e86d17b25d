"""Image bytes are user input: any bytes decode to an RGB frame or raise DataError naming the source, and the
frame size a header declares is read without decoding and bounded (issue 35, item 7)."""

from __future__ import annotations

import struct
import zlib

import cv2
import numpy as np
from hypothesis import example, given
from hypothesis import strategies as st

from robofailring.data.images import MAX_FRAME_PIXELS, MAX_FRAME_PIXELS_SETTING, decode_image, encoded_size
from robofailring.errors import DataError

FORMATS = {
    ".png": [],
    ".jpg": [],
    ".jpg progressive": [cv2.IMWRITE_JPEG_PROGRESSIVE, 1],
    ".bmp": [],
    ".webp": [cv2.IMWRITE_WEBP_QUALITY, 80],
    ".webp lossless": [cv2.IMWRITE_WEBP_QUALITY, 101],
}


def encoded(image: np.ndarray, form: str) -> bytes:
    ok, buffer = cv2.imencode(form.split()[0], image, FORMATS[form])
    assert ok
    return buffer.tobytes()


def declaring(width: int, height: int) -> bytes:
    """A 2×2 PNG whose header declares width × height (its IHDR and CRC rewritten)."""
    data = bytearray(encoded(np.zeros((2, 2, 3), np.uint8), ".png"))
    data[16:24] = struct.pack(">II", width, height)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    return bytes(data)


@given(st.sampled_from(sorted(FORMATS)), st.integers(1, 48), st.integers(1, 48), st.integers(0, 2**32 - 1))
def test_the_declared_size_is_the_decoded_size(form: str, width: int, height: int, seed: int) -> None:
    image = np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)
    data = encoded(image, form)
    assert encoded_size(data) == (width, height)
    assert decode_image(data, source="frame.bin").shape == (height, width, 3)


@given(st.integers(1, 2**31 - 1), st.integers(1, 2**31 - 1))
@example(30000, 30000)
@example(MAX_FRAME_PIXELS, 1)
@example(MAX_FRAME_PIXELS + 1, 1)
def test_a_declared_size_over_the_limit_is_refused_before_decoding(width: int, height: int) -> None:
    data = declaring(width, height)
    assert encoded_size(data) == (width, height)
    try:
        image = decode_image(data, source="bomb.png")  # 2×2 pixels stored: never the declared size
    except DataError as error:
        assert "bomb.png" in str(error)
        assert (MAX_FRAME_PIXELS_SETTING in str(error)) == (width * height > MAX_FRAME_PIXELS)
    else:
        assert width * height <= MAX_FRAME_PIXELS and image.shape[:2] == (height, width)


SIGNATURES = [
    b"",
    b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR",
    b"\xff\xd8",
    b"\xff\xd8\xff\xc0\x00\x11\x08",
    b"BM",
]


@given(st.sampled_from(SIGNATURES), st.binary(max_size=300))
@example(b"RIFF\x00\x00\x00\x00WEBPVP8X", b"\x00" * 20)
@example(b"\xff\xd8", b"\xff\xff\xff\xff\xda")
def test_any_bytes_decode_or_raise_a_data_error_naming_the_source(signature: bytes, tail: bytes) -> None:
    try:
        image = decode_image(signature + tail, source="random.bin")
    except DataError as error:
        assert "random.bin" in str(error)
    else:
        assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
