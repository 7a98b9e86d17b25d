"""Success contrast in a recording: S⁺_t and C_t per view, γ, and the nearest success frame."""

from __future__ import annotations

from typing import Final

import numpy as np
import rerun as rr

from rfr_viz._images import JPEG_MEDIA_TYPE, reference_jpeg
from rfr_viz.neighbors import changes
from rfr_viz.paths import DetectorPaths
from robofailring.detector import DetectionTrace
from robofailring.success_memory import SuccessMatch

GAMMA_COLOUR: Final[tuple[int, int, int]] = (255, 120, 200)


def _series(
    rec: rr.RecordingStream,
    path: str,
    values: np.ndarray,
    *,
    name: str,
    colour: tuple[int, int, int],
    width: float,
    fps: float,
) -> None:
    from rfr_viz.record import time_columns  # record imports this module

    values = np.asarray(values, dtype=np.float64)
    present = np.flatnonzero(np.isfinite(values))
    rec.log(path, rr.SeriesLines(colors=[colour], widths=[width], names=[name]), static=True)
    rec.send_columns(
        path, indexes=time_columns(present, fps), columns=rr.Scalars.columns(scalars=values[present])
    )


def success_info(match: SuccessMatch, t: int) -> str:
    """Markdown: which success run and frame is nearest, and how near."""
    kind = "success run" if match.run.kind == "success" else "failure run, before it failed"
    return (
        f"**{match.run.episode}**  \n"
        f"frame **{match.frame}** · S⁺ **{match.similarity:.3f}** · {kind} (now: frame {t})"
    )


def log_contrast(
    rec: rr.RecordingStream,
    trace: DetectionTrace,
    paths: DetectorPaths,
    *,
    fps: float,
    colours: list[tuple[int, int, int]],
    prefix: str = "",
) -> None:
    """`/score/<view>/success`, `/score/<view>/contrast`, `/score/gamma` and `/nearest_success/<view>`.

    Nothing is logged when the memory has no success runs (a paper-only memory).
    """
    if not trace.success_similarity:
        return
    contrasts = trace.contrast
    for position, view in enumerate(trace.views):
        colour = colours[position % len(colours)]
        faded = (colour[0] // 2 + 60, colour[1] // 2 + 60, colour[2] // 2 + 60)
        _series(
            rec,
            paths.success_score(view),
            trace.success_similarity[view],
            name=f"{prefix}{view} S⁺ (success)",
            colour=faded,
            width=1.0,
            fps=fps,
        )
        _series(
            rec,
            paths.contrast_score(view),
            contrasts[view],
            name=f"{prefix}{view} C = S⁻ − S⁺",
            colour=colour,
            width=2.0,
            fps=fps,
        )
    _series(
        rec,
        paths.gamma,
        np.full(trace.length, float(trace.gamma)),
        name=f"{prefix}γ = {trace.gamma:.3f}",
        colour=GAMMA_COLOUR,
        width=1.0,
        fps=fps,
    )
    _log_nearest_success(rec, trace, paths, fps)


def _log_nearest_success(
    rec: rr.RecordingStream, trace: DetectionTrace, paths: DetectorPaths, fps: float
) -> None:
    """The nearest success frame per view, re-logged only where it changes (and its text every frame)."""
    from rfr_viz.record import set_frame_time  # record imports this module

    cache: dict[str, bytes | None] = {}
    for view in trace.views:
        ids = trace.success_ids[view][:, None]
        for _, t, index in changes(ids):
            set_frame_time(rec, t, fps)
            match = trace.nearest_success(view, t)
            if index < 0 or match is None:
                rec.log(paths.nearest_success(view), rr.Clear(recursive=False))
                continue
            image = cache.setdefault(match.image, reference_jpeg(match.image))
            if image is None:
                rec.log(paths.nearest_success(view), rr.Clear(recursive=False))
            else:
                rec.log(
                    paths.nearest_success(view), rr.EncodedImage(contents=image, media_type=JPEG_MEDIA_TYPE)
                )
        for t in range(trace.length):
            match = trace.nearest_success(view, t)
            if match is None:
                continue
            set_frame_time(rec, t, fps)
            rec.log(
                paths.nearest_success_info(view),
                rr.TextDocument(success_info(match, t), media_type=rr.MediaType.MARKDOWN),
            )
