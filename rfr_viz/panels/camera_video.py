"""Camera streams of a recording as JPEG images or as compressed video (`rr.VideoStream`).

Real cameras (256–640 px at 15–30 fps) make per-frame JPEGs the bulk of a recording; AV1 and
H.264 store the same frames at a fraction of the bytes (measured by `bench/bench_video.py`, see
docs/codecs.md, "Camera codecs"). Video is encoded here with PyAV, without B-frames (Rerun's video streams do not take
them), one keyframe every KEYFRAME_INTERVAL frames so that showing an arbitrary frame decodes at
most that many. The native viewer decodes AV1 itself; H.264 needs ffmpeg ≥ 5.1 on the viewer's
machine. Neighbour and success-frame images stay JPEG images whatever the codec.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING, Any, Final, NamedTuple, cast

import numpy as np

from rfr_viz.codecs import CameraCodec, resolve_codec
from robofailring.data.model import Frame
from robofailring.errors import DataError, SettingError
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr

if TYPE_CHECKING:
    from av.video.codeccontext import VideoCodecContext
    from av.video.frame import VideoFrame


#: Frames between keyframes: showing any frame decodes at most this many (bench: a few ms at 480 px).
KEYFRAME_INTERVAL: Final[int] = 30
AV1_CRF: Final[int] = 35
AV1_PRESET: Final[int] = 10  # SVT-AV1 speed preset (0 slowest … 13 fastest)
H264_CRF: Final[int] = 23
CAMERA_BATCH: Final[int] = 64  # JPEG frames read, encoded and sent per column batch
CAMERA_PROPERTIES: Final[str] = "camera"  # property group: codec, per-view codecs, keyframe interval
#: PyAV encoder name and Rerun codec per video codec.
ENCODERS: Final[dict[CameraCodec, tuple[str, rr.VideoCodec]]] = {
    CameraCodec.AV1: ("libsvtav1", rr.VideoCodec.AV1),
    CameraCodec.H264: ("libx264", rr.VideoCodec.H264),
}


@dataclass(frozen=True)
class EncodedVideo:
    """A view encoded as video: one sample per frame (in frame order) and which samples are keyframes."""

    codec: CameraCodec
    samples: list[bytes]
    keyframes: list[bool]
    width: int
    height: int

    @property
    def bytes(self) -> int:
        return sum(len(sample) for sample in self.samples)


def _even(image: np.ndarray) -> np.ndarray:
    """Pad an odd width or height by one edge row/column: 4:2:0 video needs even sizes."""
    pad_h, pad_w = image.shape[0] % 2, image.shape[1] % 2
    if pad_h or pad_w:
        image = np.pad(image, ((0, pad_h), (0, pad_w), (0, 0)), mode="edge")
    return image


def _context(codec: CameraCodec, width: int, height: int, fps: float, gop: int) -> VideoCodecContext:
    with needs_extra("viz"):
        import av

    os.environ.setdefault("SVT_LOG", "1")  # SVT-AV1 logs every setting to stderr otherwise
    name, _ = ENCODERS[codec]
    context = cast("VideoCodecContext", av.CodecContext.create(name, "w"))
    context.width, context.height = width, height
    context.pix_fmt = "yuv420p"
    context.time_base = Fraction(1, 1000)
    context.framerate = Fraction(fps).limit_denominator(1000)
    context.gop_size = gop
    context.max_b_frames = 0  # Rerun video streams cannot hold B-frames
    if codec is CameraCodec.AV1:
        context.options = {"crf": str(AV1_CRF), "preset": str(AV1_PRESET)}
    else:  # Annex B with SPS/PPS before every IDR frame, so that every keyframe decodes on its own
        context.options = {
            "crf": str(H264_CRF),
            "preset": "veryfast",
            "tune": "zerolatency",
            "x264-params": f"repeat-headers=1:bframes=0:scenecut=0:keyint={gop}",
        }
    return context


class Packet(NamedTuple):
    """One encoded sample: the frame (0-based, in the order given) it shows, keyframe or not, its bytes."""

    frame: int
    keyframe: bool
    data: bytes


def _packets(context: VideoCodecContext, frame: VideoFrame | None) -> list[Packet]:
    return [Packet(int(p.pts or 0), bool(p.is_keyframe), bytes(p)) for p in context.encode(frame)]


class VideoEncoder:
    """One view's frames encoded as they come (a live stream, or a whole video by `encode_video`).

    The encoder opens at the first frame, whose size (padded to even) fixes the stream's; no
    B-frames, a keyframe every `keyframe_interval` frames. `encode` returns the packets the encoder
    gives out for that frame (possibly none yet, possibly earlier frames': each `Packet` names its
    own frame); `flush` the rest at the end of the stream. `source` names the frames in errors.
    """

    def __init__(
        self,
        codec: CameraCodec,
        *,
        fps: float,
        source: str = "camera",
        keyframe_interval: int = KEYFRAME_INTERVAL,
    ) -> None:
        if codec not in ENCODERS:
            raise SettingError(f"{codec.value!r} is not a video codec ({[c.value for c in ENCODERS]})")
        self.codec, self.fps, self.source, self.keyframe_interval = codec, fps, source, keyframe_interval
        self.frames = 0  # frames given so far
        self.shape: tuple[int, ...] | None = None  # (height, width, 3) after padding, from the first frame
        self._context: VideoCodecContext | None = None
        self._given = 0  # packets given out so far

    def encode(self, image: np.ndarray) -> list[Packet]:
        with needs_extra("viz"):
            import av

        image = _even(np.ascontiguousarray(image))
        if self._context is None:
            if min(image.shape[0], image.shape[1]) < 16:
                raise DataError(
                    f"{self.source}: frames of {image.shape[1]}×{image.shape[0]} px are too small to encode as video"
                )
            self.shape = image.shape
            self._context = _context(
                self.codec, image.shape[1], image.shape[0], self.fps, self.keyframe_interval
            )
        if image.shape != self.shape:
            assert self.shape is not None
            raise DataError(
                f"{self.source}: frame {self.frames} is {image.shape[1]}×{image.shape[0]} px, the first was "
                f"{self.shape[1]}×{self.shape[0]}: a video needs one size (use --camera-codec jpeg)"
            )
        frame = av.VideoFrame.from_ndarray(image, format="rgb24").reformat(format="yuv420p")
        frame.pts = self.frames
        self.frames += 1
        packets = _packets(self._context, frame)
        self._given += len(packets)
        return packets

    def flush(self) -> list[Packet]:
        """The packets still held by the encoder; every frame given has then had exactly one."""
        if self._context is None:
            raise DataError(f"{self.source}: no frames to encode")
        packets = _packets(self._context, None)
        self._given += len(packets)
        if self._given != self.frames:
            raise RuntimeError(
                f"{self.source}: the {self.codec.value} encoder gave {self._given} samples for {self.frames} frames"
            )
        return packets


def encode_video(
    images: Iterable[np.ndarray],
    codec: CameraCodec,
    *,
    fps: float,
    source: str = "camera",
    keyframe_interval: int = KEYFRAME_INTERVAL,
) -> EncodedVideo:
    """Encode RGB frames (all of one size) as AV1 or H.264 samples, one per frame, no B-frames,
    a keyframe every `keyframe_interval` frames. `source` names the frames in errors."""
    encoder = VideoEncoder(codec, fps=fps, source=source, keyframe_interval=keyframe_interval)
    packets = [packet for image in images for packet in encoder.encode(image)]
    packets = sorted(packets + encoder.flush(), key=lambda packet: packet.frame)
    assert encoder.shape is not None
    return EncodedVideo(
        codec=codec,
        samples=[packet.data for packet in packets],
        keyframes=[packet.keyframe for packet in packets],
        width=encoder.shape[1],
        height=encoder.shape[0],
    )


def decode_video(video: EncodedVideo, *, upto: int | None = None) -> list[np.ndarray]:
    """Decode samples back to RGB frames (from the first sample up to `upto` inclusive): for checks."""
    with needs_extra("viz"):
        import av

    name = {CameraCodec.AV1: "libdav1d", CameraCodec.H264: "h264"}[video.codec]
    context = cast("VideoCodecContext", av.CodecContext.create(name, "r"))
    last = len(video.samples) - 1 if upto is None else upto
    decoded: list[np.ndarray] = []
    for sample in video.samples[: last + 1]:
        decoded += [frame.to_ndarray(format="rgb24") for frame in context.decode(av.Packet(sample))]
    decoded += [frame.to_ndarray(format="rgb24") for frame in context.decode(None)]
    return decoded


def log_video(
    rec: rr.RecordingStream,
    entity: str,
    video: EncodedVideo,
    indexes: Sequence[rr.TimeColumn],
) -> None:
    """The codec (static) and one sample per frame of the time columns `indexes`."""
    log_video_codec(rec, entity, video.codec)
    rec.send_columns(
        entity,
        indexes=indexes,
        columns=rr.VideoStream.columns(sample=video.samples, is_keyframe=video.keyframes),
    )


def stream_video(
    rec: rr.RecordingStream,
    entity: str,
    images: Iterable[np.ndarray],
    codec: CameraCodec,
    *,
    fps: float,
    indexes: Callable[[np.ndarray], Sequence[rr.TimeColumn]],
    source: str = "camera",
) -> None:
    """Encode RGB frames as video and send the samples as they come, CAMERA_BATCH at a time: the
    same stream as `log_video(encode_video(…))`, with memory that does not grow with the episode."""
    encoder = VideoEncoder(codec, fps=fps, source=source)
    log_video_codec(rec, entity, codec)

    def send(packets: list[Packet]) -> None:
        if packets:
            rec.send_columns(
                entity,
                indexes=indexes(np.array([packet.frame for packet in packets])),
                columns=rr.VideoStream.columns(
                    sample=[packet.data for packet in packets],
                    is_keyframe=[packet.keyframe for packet in packets],
                ),
            )
            rec.flush()  # written before the next batch: a busy machine's slow sink holds no backlog

    pending: list[Packet] = []
    for image in images:
        pending += encoder.encode(image)  # no B-frames: packets come in frame order
        if len(pending) >= CAMERA_BATCH:
            send(pending)
            pending = []
    send(pending + encoder.flush())


def log_video_codec(rec: rr.RecordingStream, entity: str, codec: CameraCodec) -> None:
    """The codec of `entity`'s video stream, static: logged once, before its samples."""
    _, rerun_codec = ENCODERS[codec]
    rec.log(entity, rr.VideoStream(codec=rerun_codec), static=True)


def view_codec(frames: Sequence[Frame], count: int, codec: CameraCodec | str) -> CameraCodec:
    """The codec for the first `count` frames of a view (for `auto`: by the size of its first frame)."""
    codec = CameraCodec(codec)
    if codec is not CameraCodec.AUTO:
        return codec
    if count == 0:
        return CameraCodec.JPEG
    height, width = frames[0].load().shape[:2]
    return resolve_codec(codec, width=width, height=height, frames=count)


def send_camera_properties(
    rec: rr.RecordingStream, used: Mapping[str, CameraCodec], *, as_recorded: Sequence[str] = ()
) -> None:
    """The `camera` property group: which codec stores each view's `/camera/<view>`, and which views
    hold their video file's own samples (`as_recorded`: keyframes where the source had them)."""
    values: dict[str, Any] = {
        "codec": ", ".join(sorted({c.value for c in used.values()})),
        "views": ", ".join(f"{view}: {c.value}" for view, c in used.items()),
        "keyframe_interval": KEYFRAME_INTERVAL,
    }
    if as_recorded:
        values["as_recorded"] = ", ".join(as_recorded)
    rec.send_property(CAMERA_PROPERTIES, rr.AnyValues(**values))
