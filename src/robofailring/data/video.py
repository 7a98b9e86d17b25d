"""One PyAV frame reader for every video source (video episodes, LeRobot cameras).

Frames are decoded lazily and by timestamp: the stream's packets are listed once (no decoding)
to get every frame's presentation time, so the frame count comes from the container; a request
seeks to the keyframe before the wanted frame and decodes forward, and a run of requests in
order keeps decoding without seeking again. A long episode is never decoded whole, and a frame larger
than `images.max_frame_pixels()` is refused from the stream's declared size before any is decoded.
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.frame_ref import Container, FrameRef, register_reader
from robofailring.data.images import check_frame_size, content_digest
from robofailring.data.model import Frame, LazyFrames
from robofailring.data.open_files import OpenLimit
from robofailring.errors import DataError
from robofailring.extras import needs_extra

VIDEO_SUFFIXES: Final[tuple[str, ...]] = (".mp4", ".webm", ".mkv")
#: How frames are decoded, in their cache keys (2: turned as the file's display matrix says).
DECODED: Final[int] = 2
#: Decode forward instead of seeking when the wanted frame is at most this many frames ahead and
#: no keyframe lies between (seeking to a keyframe nearer the wanted frame is then cheaper).
_FORWARD_WINDOW: Final[int] = 48
_SEEK_COST: Final[int] = 8  # a seek (decoder flush) costs about this many decoded frames (bench_decode)
_OPEN_LIMIT: Final[int] = 16  # open containers kept (v2.1 has one file per episode and camera)


class VideoFile:
    """One video stream of a file: frame times from the container, frames decoded on demand."""

    def __init__(self, path: Path, *, stream: int = 0) -> None:
        self.path = Path(path)
        self.stream = stream
        self._times: np.ndarray | None = None
        self._pts: np.ndarray | None = None
        self._time_base: Fraction = Fraction(0)  # seconds per pts tick, set with the times
        self._keyframes: np.ndarray = np.zeros(0, dtype=np.int64)  # frame indices of keyframes
        self._digest: str | None = None
        self._container: Any = None
        self._frames: Iterator[Any] | None = None
        self._last: tuple[int, np.ndarray] | None = None  # (frame index, RGB) last decoded
        self._lock = threading.Lock()

    def __repr__(self) -> str:
        return f"VideoFile({str(self.path)!r}, stream={self.stream})"

    def __reduce__(self) -> tuple[Any, tuple[str, int]]:
        """Pickled as its path: a frame sent to another process (a Ray worker) is read through that
        process's shared reader of the file (`open_video`), so its frames decode in sequence there."""
        return _reopen, (str(self.path), self.stream)

    # ------------------------------------------------------------ container facts
    def _open(self) -> Any:
        with needs_extra("video"):
            import av

        if self._container is None:
            try:
                self._container = av.open(str(self.path))
                stream = self._container.streams.video[self.stream]
            except (av.FFmpegError, OSError) as error:
                self.close()
                raise DataError(f"cannot read video {self.path}: {_why(error)}") from error
            except IndexError as error:  # a container without that video stream ("tuple index out of range")
                self.close()
                raise DataError(
                    f"cannot read video {self.path}: it holds no video stream {self.stream}"
                ) from error
            stream.thread_type = "AUTO"
            _OPEN.remember(self)
        stream = self._container.streams.video[self.stream]
        check_frame_size(
            int(stream.codec_context.width), int(stream.codec_context.height), source=f"video {self.path}"
        )
        return self._container

    @property
    def times(self) -> np.ndarray:
        """Presentation time (s) of every frame, in order, listed from the packets (nothing decoded)."""
        if self._times is None:
            with needs_extra("video"):
                import av

            container = self._open()
            stream = container.streams.video[self.stream]
            try:
                packets = sorted(
                    (packet.pts, packet.is_keyframe)
                    for packet in container.demux(stream)
                    if packet.pts is not None and packet.size > 0
                )
            except av.FFmpegError as error:
                raise DataError(f"cannot read video {self.path}: {_why(error)}") from error
            if not packets:
                raise DataError(f"video {self.path} holds no frames in video stream {self.stream}")
            self._pts = np.asarray([pts for pts, _ in packets], dtype=np.int64)
            self._keyframes = np.flatnonzero([key for _, key in packets])
            self._time_base = Fraction(stream.time_base)
            self._times = self._pts.astype(np.float64) * float(self._time_base)
            self._frames = None  # demuxing moved the read position
        return self._times

    @property
    def count(self) -> int:
        """Frames in the stream, counted from the container's packets."""
        return len(self.times)

    @property
    def fps(self) -> float | None:
        """Frames per second of the stream as its frame times show: (frames - 1) / their span.

        None for a single frame or frames that all share one time. Measured from the packets rather
        than taken from the stream's declared rate, which may be a timebase (120/1) and not the rate.
        """
        count = len(self.times)  # lists the packets' pts and the time base
        pts = self._pts if self._pts is not None else np.zeros(1, dtype=np.int64)
        span = int(pts[-1] - pts[0]) * self._time_base  # exact: 6 fps gives 6.0, not 6.000000000000001
        return float((count - 1) / span) if count > 1 and span > 0 else None

    def index_at(self, seconds: float) -> int:
        """The frame shown at `seconds` (the nearest frame time; an error beyond half a frame)."""
        times = self.times
        position = int(np.clip(np.searchsorted(times, seconds), 0, len(times) - 1))
        if position > 0 and abs(times[position - 1] - seconds) <= abs(times[position] - seconds):
            position -= 1
        period = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
        if abs(times[position] - seconds) > period / 2 + 1e-4:
            raise DataError(
                f"video {self.path} has no frame at {seconds:.4f} s (its frames span "
                f"{times[0]:.4f}–{times[-1]:.4f} s)"
            )
        return position

    def digest(self) -> str:
        """A digest of the whole file's bytes (read once), the base of its frames' cache keys."""
        if self._digest is None:
            hasher = hashlib.blake2b(digest_size=16)
            try:
                with self.path.open("rb") as handle:
                    while chunk := handle.read(1 << 20):
                        hasher.update(chunk)
            except OSError as error:
                raise DataError(f"cannot read video {self.path}: {error.strerror or error}") from error
            self._digest = hasher.hexdigest()
        return self._digest

    # ------------------------------------------------------------ decoding
    def decode(self, index: int) -> np.ndarray:
        """Frame `index` of the stream as (H, W, 3) uint8 RGB."""
        with needs_extra("video"):
            import av

        times = self.times
        if not 0 <= index < len(times):
            raise DataError(f"video {self.path} has {len(times)} frames; no frame {index}")
        with self._lock:
            if self._last is not None and self._last[0] == index:
                return self._last[1]
            assert self._pts is not None
            target = int(self._pts[index])
            ahead = self._last is not None and 0 < index - self._last[0] <= _FORWARD_WINDOW
            if ahead and self._last is not None:  # seek when a keyframe near the target saves decoding
                position = np.searchsorted(self._keyframes, index, side="right") - 1
                keyframe = int(self._keyframes[position]) if position >= 0 else -1
                ahead = index - self._last[0] <= index - keyframe + 1 + _SEEK_COST
            # where to decode from: on from the last frame (when it is just behind), the keyframe before the
            # target, and on a miss the stream's start: where frames decode out of timestamp order, a seek
            # (by decoding time) can land past the wanted frame
            starts = ([None] if ahead and self._frames is not None else []) + [target, int(self._pts[0])]
            for start in dict.fromkeys(starts):
                try:
                    image = self._decode_at(target, index, start=start)
                except av.FFmpegError as error:
                    self._frames = None
                    raise DataError(
                        f"cannot decode frame {index} of video {self.path}: {_why(error)}"
                    ) from error
                if image is not None:
                    self._last = (index, image)
                    return np.ascontiguousarray(image)
        raise DataError(
            f"cannot decode frame {index} of video {self.path}: the stream ended before a frame with its "
            "timestamp (the file's timestamps may be out of order; re-encode it, e.g. with ffmpeg)"
        )

    def _decode_at(self, target: int, index: int, *, start: int | None) -> np.ndarray | None:
        """The decoded frame whose timestamp is exactly `target`, decoding on from the last one (`start`
        None) or from the keyframe at or before timestamp `start`; None when the stream ends first. Exact:
        where a file's frames decode out of timestamp order, the first frame past `target` is another
        frame, never to be given as this one."""
        if start is not None:
            container = self._open()
            stream = container.streams.video[self.stream]
            container.seek(start, stream=stream, backward=True, any_frame=False)
            self._frames = container.decode(stream)
        assert self._frames is not None
        for frame in self._frames:
            if frame.pts != target:
                continue
            check_frame_size(frame.width, frame.height, source=f"frame {index} of video {self.path}")
            image = frame.to_ndarray(format="rgb24")
            turns = round(frame.rotation / 90) % 4  # a phone's portrait clip: shown turned, as players do
            return np.rot90(image, turns) if turns else image
        self._frames = None
        return None

    def close(self) -> None:
        if self._container is not None:
            self._container.close()
        self._container = None
        self._frames = None
        self._last = None


def _why(error: BaseException) -> str:
    return str(getattr(error, "strerror", None) or error)


_OPEN: OpenLimit[VideoFile] = OpenLimit(_OPEN_LIMIT)


_FILES: dict[tuple[str, int], VideoFile] = {}


def open_video(path: Path, *, stream: int = 0) -> VideoFile:
    """The shared reader of one file's stream (frames of one file share its decoder and digest)."""
    key = (str(Path(path).resolve()), stream)
    found = _FILES.get(key)
    if found is None:
        found = _FILES[key] = VideoFile(Path(path), stream=stream)
    return found


def _reopen(path: str, stream: int) -> VideoFile:
    return open_video(Path(path), stream=stream)


@dataclass(frozen=True)
class VideoFrame:
    """Where one frame lives in a video: its file's reader and the frame's time or index."""

    video: VideoFile
    index: int | None = None  # frame index in the stream, or
    seconds: float | None = None  # presentation time (LeRobot: from_timestamp + timestamp)

    def frame_index(self) -> int:
        return self.index if self.index is not None else self.video.index_at(float(self.seconds or 0.0))

    def load(self) -> np.ndarray:
        return self.video.decode(self.frame_index())

    def content_key(self) -> str:
        """Keyed by (file content, stream, frame index): no decoding needed to find a cached embedding."""
        key = f"video:{DECODED}:{self.video.digest()}:{self.video.stream}:{self.frame_index()}"
        return content_digest(key.encode())

    @property
    def reference(self) -> str:
        return str(FrameRef.video(self.video.path, self.frame_index()))


class VideoFrames(LazyFrames):
    """The frames of a video (all of them, or those at given times) as a lazy sequence of `Frame`."""

    def __init__(self, video: VideoFile, times: Sequence[float] | np.ndarray | None = None) -> None:
        self.video = video
        self._times = None if times is None else np.asarray(times, dtype=np.float64)

    def __len__(self) -> int:
        return self.video.count if self._times is None else len(self._times)

    @property
    def whole_file(self) -> bool:
        """Every frame of the file in order (a video-episode folder), not frames picked by time."""
        return self._times is None

    @property
    def fps(self) -> float | None:
        """The container's rate for a whole file (a video-episode folder's view); frames picked by time: None."""
        return self.video.fps if self.whole_file else None

    def frame(self, index: int) -> Frame:
        if self._times is None:
            return Frame(source=VideoFrame(self.video, index=index))
        return Frame(source=VideoFrame(self.video, seconds=float(self._times[index])))

    def __repr__(self) -> str:
        return f"VideoFrames({self.video!r}, {len(self) if self._times is not None else '?'} frames)"


def _read_video_frame(ref: FrameRef) -> np.ndarray | None:
    """The frame a video frame's reference (a memory entry's start/end) points at, or None when its file is gone."""
    if ref.index is None or not Path(ref.file).is_file():
        return None
    return open_video(Path(ref.file)).decode(ref.index)


register_reader(Container.VIDEO, _read_video_frame)


def video_files(directory: Path) -> list[Path]:
    """The video files directly in a folder (.mp4, .webm, .mkv), by name."""
    return sorted(p for p in Path(directory).iterdir() if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES)
