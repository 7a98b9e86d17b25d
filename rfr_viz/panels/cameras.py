"""The camera panel of a replay: each view's frames as JPEGs or one video stream, whichever codec it takes."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.camera_video import (
    CAMERA_BATCH,
    log_video,
    send_camera_properties,
    stream_video,
    view_codec,
)
from rfr_viz.panels.images import JPEG_MEDIA_TYPE, frame_jpeg
from rfr_viz.panels.video_passthrough import passthrough
from rfr_viz.paths import DEFAULT_FPS, camera
from robofailring.data.model import Trajectory
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr


def log_camera_views(
    rec: rr.RecordingStream,
    trajectory: Trajectory,
    *,
    views: Sequence[str],
    length: int,
    indexes: Callable[[np.ndarray], list[rr.TimeColumn]],
    codec: CameraCodec | str = CameraCodec.JPEG,
) -> dict[str, CameraCodec]:
    """`/camera/<view>` for the first `length` frames of each view, as JPEGs (sent in column
    batches, never raw pixels) or as one video stream; the codec of each view is recorded in the
    `camera` property group. A view read from a video file already in that codec, without B-frames,
    is logged as the file's own samples (rfr_viz.panels.video_passthrough), not re-encoded. Returns the
    codec used per view."""
    used: dict[str, CameraCodec] = {}
    as_recorded: list[str] = []  # views logged as their video file's own samples
    for view in views:
        frames = trajectory.views[view]
        count = min(length, len(frames))
        used[view] = view_codec(frames, count, codec)
        if used[view] is CameraCodec.JPEG:
            for start in range(0, count, CAMERA_BATCH):
                blobs = [frame_jpeg(frame) for frame in frames[start : min(start + CAMERA_BATCH, count)]]
                rec.send_columns(
                    camera(view),
                    indexes=indexes(np.arange(start, start + len(blobs))),
                    columns=rr.EncodedImage.columns(blob=blobs, media_type=[JPEG_MEDIA_TYPE] * len(blobs)),
                )
                rec.flush()  # written before the next batch: a busy machine's slow sink holds no backlog
        else:
            source = f"{trajectory.key} [{view}]"
            fps = float(trajectory.frame_rate or DEFAULT_FPS)
            video = passthrough(frames, count, used[view])
            if video is not None:
                as_recorded.append(view)
                log_video(rec, camera(view), video, indexes(np.arange(count)))
            else:
                images = (frame.load() for frame in frames[:count])
                stream_video(rec, camera(view), images, used[view], fps=fps, indexes=indexes, source=source)
    send_camera_properties(rec, used, as_recorded=as_recorded)
    return used
