"""HDF5 image datasets read lazily with h5py: a frame is one row sliced on demand, never the whole array.

Files are opened per read through a small cache of open handles (`_OPEN_LIMIT`), so a dataset of
many episode files keeps few open. A frame's reference names its file, dataset and row (`frame_ref`); its
content key digests the row's own bytes (raw pixels or the stored JPEG) and how they are read, so
nothing else is read. How a dataset's rows are read (`RowFormat`) is decided from the file alone
(`row_format`), by the layouts and by a memory's references alike: encoded rows are ALOHA's, JPEGs
of the camera's RGB array given to `cv2.imencode` as it was (decoded without a channel swap), and a
file whose `data` group says `macros_image_convention` = `opengl` (LIBERO) stores its images bottom
row first (flipped back when read). A row is read only when its declared frame size is neither empty
(no height or width) nor over `images.max_frame_pixels()` (an encoded row: its bytes within three
bytes a pixel of it), and what h5py raises for a damaged file (a corrupt object header is a KeyError)
is a DataError naming the file (`hdf5_faults`).
"""

from __future__ import annotations

import os
import threading
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.frame_ref import Container, FrameRef, register_reader
from robofailring.data.images import (
    MAX_FRAME_PIXELS_SETTING,
    as_rgb,
    check_frame_size,
    content_digest,
    decode_image,
    max_frame_pixels,
)
from robofailring.data.model import Frame, LazyFrames
from robofailring.errors import DataError
from robofailring.extras import needs_extra

HDF5_SUFFIXES: Final[tuple[str, ...]] = (".hdf5", ".h5", ".he5")
_OPEN_LIMIT: Final[int] = 8
_OPEN: OrderedDict[str, tuple[Any, tuple[int, int]]] = OrderedDict()  # path -> (handle, mtime, size)
_LOCK = threading.RLock()


def is_hdf5(path: Path) -> bool:
    return Path(path).is_file() and Path(path).suffix.lower() in HDF5_SUFFIXES


def open_hdf5(path: Path) -> Any:
    """The shared read-only h5py handle of a file (at most `_OPEN_LIMIT` stay open)."""
    with needs_extra("hdf5"):
        import h5py

    key = str(Path(path).resolve())
    try:
        stat = os.stat(key)
    except OSError as error:
        raise DataError(f"cannot read HDF5 file {path}: {error.strerror or error}") from error
    version = (stat.st_mtime_ns, stat.st_size)  # a file written again is opened again
    with _LOCK:
        found = _OPEN.pop(key, None)
        if found is not None and found[1] == version and found[0].id.valid:
            _OPEN[key] = found
            return found[0]
        if found is not None:
            found[0].close()
        try:
            handle = h5py.File(key, "r")
        except OSError as error:
            raise DataError(f"cannot read HDF5 file {path}: {error}") from error
        _OPEN[key] = (handle, version)
        while len(_OPEN) > _OPEN_LIMIT:
            _, (oldest, _) = _OPEN.popitem(last=False)
            oldest.close()
        return handle


@contextmanager
def hdf5_faults(path: Path | str) -> Iterator[None]:
    """What h5py raises for a damaged file (a corrupt object header is a KeyError, a failed visit a
    RuntimeError, an unreadable chunk an OSError) as one DataError naming the file."""
    try:
        yield
    except (KeyError, RuntimeError, OSError) as error:
        why = error.args[0] if isinstance(error, KeyError) and error.args else error
        raise DataError(f"cannot read HDF5 file {path}: {why} (a damaged or unfinished file?)") from error


def unreadable(path: Path) -> str | None:
    """Why an HDF5 file cannot be opened (an error naming it), None when it opens: what a folder whose
    files match no layout says of a damaged one."""
    try:
        with hdf5_faults(path):
            open_hdf5(path)
    except DataError as error:
        return str(error)
    return None


def describe(handle: Any, *, limit: int = 12) -> str:
    """What an HDF5 file holds, for errors: its datasets with shapes (the first `limit`)."""
    found: list[str] = []

    def visit(name: str, item: Any) -> None:
        if hasattr(item, "shape"):
            found.append(f"/{name} {tuple(item.shape)} {item.dtype}")

    handle.visititems(visit)
    shown = "; ".join(found[:limit]) + (f"; … ({len(found)} datasets)" if len(found) > limit else "")
    return shown or "no datasets (groups: " + (", ".join(handle.keys()) or "none") + ")"


def is_image_array(item: Any) -> bool:
    """An (N, H, W, 3) uint8 dataset: one RGB camera's frames."""
    return hasattr(item, "shape") and len(item.shape) == 4 and item.shape[-1] == 3 and item.dtype == np.uint8


def is_jpeg_rows(item: Any) -> bool:
    """An (N, L) uint8 dataset of padded encoded images (ALOHA's `compress`)."""
    return hasattr(item, "shape") and len(item.shape) == 2 and item.dtype == np.uint8


@dataclass(frozen=True)
class RowFormat:
    """How the rows of an image dataset are stored, and what reading one undoes."""

    encoded: bool = False  # padded JPEG rows of RGB arrays (ALOHA's `compress`), else raw (H, W, 3) pixels
    flipped: bool = False  # bottom row first (LIBERO's `macros_image_convention` = opengl)

    @property
    def tag(self) -> str:
        """A part of the content key: the same bytes read another way are another image."""
        return ("rgb-jpeg:" if self.encoded else "") + ("flipud:" if self.flipped else "")


def row_format(handle: Any, dataset: str) -> RowFormat:
    """How the rows of `dataset` in an open file are read (the one decision, see the module's docstring)."""
    data = handle.get("data")
    convention = data.attrs.get("macros_image_convention") if data is not None else None
    if isinstance(convention, bytes):
        convention = convention.decode()
    return RowFormat(
        encoded=not is_image_array(handle[dataset]),
        flipped=str(convention).strip().lower() == "opengl",
    )


@dataclass(frozen=True)
class HDF5Frame:
    """Row `index` of an image dataset: raw (H, W, 3) pixels, or a padded JPEG row of `length` bytes."""

    file: Path
    dataset: str
    index: int
    form: RowFormat = RowFormat()
    length: int | None = None  # the encoded image's bytes in the padded row (None: the whole row)

    def _row(self) -> np.ndarray:
        with _LOCK:
            handle = open_hdf5(self.file)
            try:
                item = handle[self.dataset]
                self._check_size(tuple(item.shape))
                row = np.asarray(item[self.index])
            except (KeyError, IndexError, OSError, RuntimeError) as error:
                raise DataError(f"cannot read {self.reference}: {error}") from error
        return row if self.length is None else row[: self.length]

    def _check_size(self, shape: tuple[int, ...]) -> None:
        """Refuse a row larger than a frame may be, or of no pixels, from the dataset's declared shape (nothing read)."""
        if not self.form.encoded and len(shape) >= 3:
            if shape[1] < 1 or shape[2] < 1:  # OpenCV asserts on an empty image when it is resized
                raise DataError(
                    f"{self.reference}: the dataset's frames are {shape[2]}×{shape[1]} pixels, empty "
                    f"(shape {shape})"
                )
            check_frame_size(shape[2], shape[1], source=self.reference)
        elif self.form.encoded and len(shape) == 2 and shape[1] > 3 * max_frame_pixels():
            raise DataError(
                f"{self.reference}: an encoded row of {shape[1]:,} bytes is larger than a raw frame of the "
                f"{max_frame_pixels():,} pixels a frame may have; set {MAX_FRAME_PIXELS_SETTING} to raise it"
            )

    def load(self) -> np.ndarray:
        row = self._row()
        if self.form.encoded:
            image = decode_image(row.tobytes(), source=self.reference, stored_rgb=True)
        else:
            image = as_rgb(row, source=self.reference)
        return np.ascontiguousarray(image[::-1]) if self.form.flipped else image

    def content_key(self) -> str:
        row = self._row()
        return content_digest(f"hdf5:{row.shape}:{self.form.tag}".encode() + row.tobytes())

    @property
    def reference(self) -> str:
        return str(FrameRef.hdf5(self.file, self.dataset, self.index))


class HDF5Frames(LazyFrames):
    """The frames of one image dataset as a lazy sequence of `Frame` (nothing read until loaded)."""

    def __init__(
        self,
        file: Path,
        dataset: str,
        count: int,
        *,
        form: RowFormat = RowFormat(),
        lengths: Sequence[int] | None = None,
    ) -> None:
        self.file, self.dataset, self.size, self.form = Path(file), dataset, count, form
        self.lengths = None if lengths is None else [int(n) for n in lengths]

    def __len__(self) -> int:
        return self.size

    def frame(self, index: int) -> Frame:
        length = self.lengths[index] if self.lengths is not None else None
        return Frame(source=HDF5Frame(self.file, self.dataset, index, form=self.form, length=length))

    def __repr__(self) -> str:
        return f"HDF5Frames({str(self.file)!r}, {self.dataset!r}, {self.size} frames)"


def _read_hdf5_row(ref: FrameRef) -> np.ndarray | None:
    """The row an HDF5 row's reference points at, or None when its file or dataset is not there."""
    if ref.index is None or not Path(ref.file).is_file():
        return None
    handle = open_hdf5(Path(ref.file))
    with hdf5_faults(ref.file):
        if handle.get(ref.inner) is None:
            return None
        form = row_format(handle, ref.inner)
    return HDF5Frame(Path(ref.file), ref.inner, ref.index, form=form).load()


register_reader(Container.HDF5, _read_hdf5_row)
