"""A video source's own samples in a recording, when re-encoding them would change nothing needed.

A view read from a video-episode folder (`<episode>/<view>.mp4`, rfr_viz's readers in
robofailring.data.video) whose file is already AV1 or H.264 — the codec asked for — and holds no
B-frames (which Rerun's video streams cannot take) is logged as the file's demuxed packets: AV1
samples as they are (OBUs), H.264 converted from MP4's length-prefixed form to Annex B (with the
SPS/PPS before every keyframe) by FFmpeg's `h264_mp4toannexb` filter. Anything else — another
codec, B-frames, frames picked by time (LeRobot episodes in a shared file), a packet count that
does not match the frames — is re-encoded by rfr_viz.panels.camera_video as before.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.camera_video import ENCODERS, EncodedVideo
from robofailring.data.model import Frame
from robofailring.data.video import VideoFrames
from robofailring.extras import needs_extra

#: FFmpeg's name of each codec the samples may be taken from as they are.
SOURCE_CODECS: Final[dict[CameraCodec, str]] = {CameraCodec.AV1: "av1", CameraCodec.H264: "h264"}


def passthrough(frames: Sequence[Frame], count: int, codec: CameraCodec) -> EncodedVideo | None:
    """The first `count` samples of the view's video file, when they can be logged as they are."""
    with needs_extra("viz"):
        import av

    if codec not in ENCODERS or not isinstance(frames, VideoFrames) or not frames.whole_file or count < 1:
        return None
    video = frames.video
    with av.open(str(video.path)) as container:
        stream = container.streams.video[video.stream]
        context = stream.codec_context
        if context.codec.canonical_name != SOURCE_CODECS[codec] or context.has_b_frames:
            return None
        packets = [packet for packet in container.demux(stream) if packet.size]
        times = [-1 if packet.pts is None else int(packet.pts) for packet in packets]
        if len(packets) != video.count or min(times, default=0) < 0 or times != sorted(set(times)):
            return None  # not one packet per frame in presentation order
        packets = packets[:count]
        keyframes = [bool(packet.is_keyframe) for packet in packets]
        if not keyframes[0]:
            return None
        if codec is CameraCodec.H264:
            with needs_extra("viz"):
                from av.bitstream import BitStreamFilterContext

            annexb = BitStreamFilterContext("h264_mp4toannexb", stream)
            converted = [out for packet in packets for out in annexb.filter(packet)] + annexb.filter(None)
            if len(converted) != len(packets):
                return None
            samples = [bytes(packet) for packet in converted]
        else:
            samples = [bytes(packet) for packet in packets]
        return EncodedVideo(codec, samples, keyframes, int(context.width), int(context.height))
