"""A live session's `/camera/<view>` streams: a JPEG per frame, or video encoded frame by frame.

Live frames arrive one at a time and their size is not known before the first, so `auto` means JPEG
here. With AV1 or H.264 each view has one `VideoEncoder` (rfr_viz.panels.camera_video: the settings of a
replay's video, no B-frames, the same keyframe interval), opened at the view's first frame; every
packet it gives out is logged as a `VideoStream` sample at the frame it shows (an encoder may give a
frame's packet a few frames later), and `finish` flushes the rest at the end of the stream.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.camera_video import Packet, VideoEncoder, log_video_codec, send_camera_properties
from rfr_viz.panels.images import JPEG_MEDIA_TYPE, JPEG_QUALITY, frame_jpeg
from rfr_viz.panels.scores import set_frame_time
from rfr_viz.paths import camera
from robofailring.data.images import as_rgb, encode_jpeg
from robofailring.data.model import Frame
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr


def live_codec(codec: CameraCodec | str) -> CameraCodec:
    """The codec of a live stream: `codec` itself, `auto` as JPEG (no size is known in advance)."""
    codec = CameraCodec(codec)
    return CameraCodec.JPEG if codec is CameraCodec.AUTO else codec


class LiveCameras:
    """Logs each view's live frames to `/camera/<view>` with one codec, and says which in `camera`."""

    def __init__(
        self,
        rec: rr.RecordingStream,
        views: Sequence[str],
        *,
        codec: CameraCodec | str = CameraCodec.JPEG,
        fps: float,
        name: str = "live",
    ) -> None:
        self.rec, self.fps, self.name = rec, fps, name
        self.codec = live_codec(codec)
        self._encoders: dict[str, VideoEncoder] = {}
        self._frame_t: dict[str, list[int]] = {}  # view -> the step t of each frame given to its encoder
        send_camera_properties(rec, dict.fromkeys(views, self.codec))

    def log(self, view: str, frame: np.ndarray | Frame, t: int) -> None:
        """Log (JPEG) or encode (video) the frame of `view` at step `t`."""
        if self.codec is CameraCodec.JPEG:
            blob = (
                frame_jpeg(frame)
                if isinstance(frame, Frame)
                else encode_jpeg(as_rgb(frame), quality=JPEG_QUALITY)
            )
            self.rec.log(camera(view), rr.EncodedImage(contents=blob, media_type=JPEG_MEDIA_TYPE))
            return
        encoder = self._encoders.get(view)
        if encoder is None:
            encoder = VideoEncoder(self.codec, fps=self.fps, source=f"{self.name} [{view}]")
            self._encoders[view], self._frame_t[view] = encoder, []
            log_video_codec(self.rec, camera(view), self.codec)
        source = f"{self.name} [{view}] frame {t}"
        image = frame.load() if isinstance(frame, Frame) else as_rgb(frame, source=source)
        self._frame_t[view].append(t)
        if self._log_packets(view, encoder.encode(image)):
            set_frame_time(self.rec, t, self.fps)  # back to this step's frame for what is logged next

    def finish(self) -> None:
        """Flush every view's encoder: the frames it still held are logged at their own frames."""
        for view, encoder in self._encoders.items():
            self._log_packets(view, encoder.flush())

    def _log_packets(self, view: str, packets: list[Packet]) -> bool:
        """Each packet at the frame it shows (this moves the recording's time); whether any was."""
        for packet in packets:  # logged (not sent as columns) so that the batcher packs them into chunks
            set_frame_time(self.rec, self._frame_t[view][packet.frame], self.fps)
            self.rec.log(
                camera(view), rr.VideoStream.from_fields(sample=packet.data, is_keyframe=packet.keyframe)
            )
        return bool(packets)
