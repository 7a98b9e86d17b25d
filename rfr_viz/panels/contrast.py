"""Success contrast in a recording: the success frame nearest to each view's query ("what normal looked like
here") and its text."""

from __future__ import annotations

import numpy as np

from rfr_viz.panels.images import JPEG_MEDIA_TYPE, ReferenceJpegs
from rfr_viz.panels.neighbors import changes
from rfr_viz.panels.scores import ROW_BATCH, time_columns
from rfr_viz.paths import DetectorPaths
from robofailring.detection.detector import DetectionTrace
from robofailring.extras import needs_extra
from robofailring.memory.success import SuccessMatch

with needs_extra("viz"):
    import rerun as rr


def log_nearest_success(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    view: str,
    match: SuccessMatch | None,
    *,
    t: int,
    images: ReferenceJpegs,
    image: bool = True,
) -> None:
    """At the current time: the nearest success frame of `view` (`image`: its picture too) and its text."""
    if match is None:
        rec.log(paths.nearest_success(view), rr.Clear(recursive=False))
        return
    if image:
        jpeg = _success_jpeg(match, images)
        if jpeg is None:
            rec.log(paths.nearest_success(view), rr.Clear(recursive=False))
        else:
            rec.log(paths.nearest_success(view), rr.EncodedImage(contents=jpeg, media_type=JPEG_MEDIA_TYPE))
    text = _success_text(match, t, images)
    rec.log(paths.nearest_success_info(view), rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN))


def _success_jpeg(match: SuccessMatch, images: ReferenceJpegs) -> bytes | None:
    """The match's picture as JPEG, read and encoded once per recording (None: missing or not to be read)."""
    return images.get(match.image)


def _success_text(match: SuccessMatch, t: int, images: ReferenceJpegs) -> str:
    """The info text, naming the picture when it was looked for and is missing."""
    text = success_info(match, t)
    if images.looked_for_in_vain(match.image):
        text += f"  \n{images.absence(match.image)}"
    return text


def success_info(match: SuccessMatch, t: int) -> str:
    """Markdown: which success run and frame is nearest, and how near."""
    kind = "success run" if match.run.kind == "success" else "failure run, before it failed"
    return (
        f"**{match.run.episode}**  \n"
        f"frame **{match.frame}** · S⁺ **{match.similarity:.3f}** · {kind} (now: frame {t})"
    )


def log_nearest_successes(
    rec: rr.RecordingStream, trace: DetectionTrace, paths: DetectorPaths, *, fps: float
) -> None:
    """`/nearest_success/<view>` (the picture) and its info text, per scored frame; nothing when the memory has
    no success runs (a paper-only memory). S⁺_t and the rules' scores are the scores panel's."""
    if trace.success_similarity:
        _log_nearest_success(rec, trace, paths, fps)


def _log_nearest_success(
    rec: rr.RecordingStream, trace: DetectionTrace, paths: DetectorPaths, fps: float
) -> None:
    """The nearest success frame per view, its picture re-logged only where it changes (text every
    scored frame; with a stride, unscored frames have none): the rows `log_nearest_success` logs one
    frame at a time, sent as columns ROW_BATCH frames at a time and flushed, so a long episode holds
    no more pending rows than a short one."""
    cache = ReferenceJpegs(trace.memory.image_roots)
    scored = trace.scored_frames
    for view in trace.views:
        ids = trace.success_ids[view][scored]
        changed = {int(scored[step]) for _, step, _ in changes(ids[:, None])}
        for start in range(0, len(scored), ROW_BATCH):
            frames = [int(t) for t in scored[start : start + ROW_BATCH]]
            matches = [(t, trace.nearest_success(view, t)) for t in frames]
            _send_nearest_success(rec, paths, view, matches, changed=changed, images=cache, fps=fps)
            rec.flush()


def _send_nearest_success(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    view: str,
    matches: list[tuple[int, SuccessMatch | None]],
    *,
    changed: set[int],
    images: ReferenceJpegs,
    fps: float,
) -> None:
    """One batch of `log_nearest_success`'s rows as columns: a Clear where there is no match (or its
    picture is missing), the picture where it changed, the text wherever there is a match."""
    cleared: list[int] = []
    pictured: list[tuple[int, bytes]] = []
    texts: list[tuple[int, str]] = []
    for t, match in matches:
        if match is None:
            cleared.append(t)
            continue
        if t in changed:
            jpeg = _success_jpeg(match, images)
            if jpeg is None:
                cleared.append(t)
            else:
                pictured.append((t, jpeg))
        texts.append((t, _success_text(match, t, images)))
    at = lambda frames: time_columns(np.asarray(frames, dtype=np.int64), fps)  # noqa: E731
    if cleared:
        rec.send_columns(
            paths.nearest_success(view),
            indexes=at(cleared),
            columns=rr.Clear.columns(is_recursive=[False] * len(cleared)),
        )
    if pictured:
        rec.send_columns(
            paths.nearest_success(view),
            indexes=at([t for t, _ in pictured]),
            columns=rr.EncodedImage.columns(
                blob=[jpeg for _, jpeg in pictured], media_type=[JPEG_MEDIA_TYPE] * len(pictured)
            ),
        )
    if texts:
        rec.send_columns(
            paths.nearest_success_info(view),
            indexes=at([t for t, _ in texts]),
            columns=rr.TextDocument.columns(
                text=[text for _, text in texts], media_type=[rr.MediaType.MARKDOWN.value] * len(texts)
            ),
        )
