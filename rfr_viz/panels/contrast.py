"""Success contrast in a recording: S⁺_t, C_t and N_t per view, γ and η, and the nearest success frame."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from rfr_viz.panels.images import JPEG_MEDIA_TYPE, reference_jpeg
from rfr_viz.panels.neighbors import changes
from rfr_viz.panels.scores import ROW_BATCH, threshold_label, time_columns
from rfr_viz.paths import DetectorPaths
from rfr_viz.styles import ETA_COLOUR, GAMMA_COLOUR
from robofailring.detection.band import Band
from robofailring.detection.detector import DetectionTrace
from robofailring.detection.rules import CONTRAST, NOVELTY
from robofailring.extras import needs_extra
from robofailring.memory.success import SuccessMatch

with needs_extra("viz"):
    import rerun as rr


def _series(
    rec: rr.RecordingStream,
    path: str,
    values: np.ndarray,
    *,
    fps: float,
) -> None:
    values = np.asarray(values, dtype=np.float64)
    present = np.flatnonzero(np.isfinite(values))
    rec.send_columns(
        path, indexes=time_columns(present, fps), columns=rr.Scalars.columns(scalars=values[present])
    )


def log_contrast_styles(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    *,
    views: list[str],
    gamma: float,
    eta: float,
    colours: list[tuple[int, int, int]],
    prefix: str = "",
    failures: bool = True,
    bands: Mapping[str, Band] | None = None,
) -> None:
    """Static line styles of S⁺_t, C_t and N_t per view and of γ and η (a replay's and a live stream's);
    without failure entries of the task (`failures` False) C_t and γ are left out. A rule with a band
    (`bands`, by rule name) has its threshold named as the line over time it is."""
    bands = bands or {}
    for position, view in enumerate(views):
        colour = colours[position % len(colours)]
        faded = (colour[0] // 2 + 60, colour[1] // 2 + 60, colour[2] // 2 + 60)
        rec.log(
            paths.success_score(view),
            rr.SeriesLines(colors=[faded], widths=[1.0], names=[f"{prefix}{view} S⁺ (success)"]),
            static=True,
        )
        if failures:
            rec.log(
                paths.contrast_score(view),
                rr.SeriesLines(colors=[colour], widths=[2.0], names=[f"{prefix}{view} C = S⁻ − S⁺"]),
                static=True,
            )
        rec.log(
            paths.novelty_score(view),
            rr.SeriesLines(
                colors=[colour], widths=[2.0 if not failures else 1.0], names=[f"{prefix}{view} N = 1 − S⁺"]
            ),
            static=True,
        )
    if failures:
        rec.log(
            paths.gamma,
            rr.SeriesLines(
                colors=[GAMMA_COLOUR],
                widths=[1.0],
                names=[prefix + threshold_label(CONTRAST, gamma, bands.get(CONTRAST.name))],
            ),
            static=True,
        )
    rec.log(
        paths.eta,
        rr.SeriesLines(
            colors=[ETA_COLOUR],
            widths=[1.0],
            names=[prefix + threshold_label(NOVELTY, eta, bands.get(NOVELTY.name))],
        ),
        static=True,
    )


def log_nearest_success(
    rec: rr.RecordingStream,
    paths: DetectorPaths,
    view: str,
    match: SuccessMatch | None,
    *,
    t: int,
    images: dict[str, bytes | None],
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


def _success_jpeg(match: SuccessMatch, images: dict[str, bytes | None]) -> bytes | None:
    """The match's picture as JPEG, read and encoded once per recording (None: the file is missing)."""
    if match.image not in images:
        images[match.image] = reference_jpeg(match.image)
    return images[match.image]


def _success_text(match: SuccessMatch, t: int, images: dict[str, bytes | None]) -> str:
    """The info text, naming the picture when it was looked for and is missing."""
    text = success_info(match, t)
    if images.get(match.image, b"") is None:
        text += f"  \n**image not found:** `{match.image}`"
    return text


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
    """`/score/<view>/{success,contrast,novelty}`, `/score/gamma`, `/score/eta` and `/nearest_success/<view>`.

    Nothing is logged when the memory has no success runs (a paper-only memory); C_t and γ are
    left out for a task without failure entries (judged by novelty alone).
    """
    if not trace.success_similarity:
        return
    failures = trace.has_failures
    log_contrast_styles(
        rec,
        paths,
        views=trace.views,
        gamma=trace.gamma,
        eta=trace.eta,
        colours=colours,
        prefix=prefix,
        failures=failures,
        bands=trace.bands,
    )
    contrasts, novelties = trace.contrast, trace.novelty
    for view in trace.views:
        _series(rec, paths.success_score(view), trace.success_similarity[view], fps=fps)
        if failures:
            _series(rec, paths.contrast_score(view), contrasts[view], fps=fps)
        _series(rec, paths.novelty_score(view), novelties[view], fps=fps)
    if failures:
        _series(rec, paths.gamma, trace.threshold_line(CONTRAST), fps=fps)
    _series(rec, paths.eta, trace.threshold_line(NOVELTY), fps=fps)
    _log_nearest_success(rec, trace, paths, fps)


def _log_nearest_success(
    rec: rr.RecordingStream, trace: DetectionTrace, paths: DetectorPaths, fps: float
) -> None:
    """The nearest success frame per view, its picture re-logged only where it changes (text every
    scored frame; with a stride, unscored frames have none): the rows `log_nearest_success` logs one
    frame at a time, sent as columns ROW_BATCH frames at a time and flushed, so a long episode holds
    no more pending rows than a short one."""
    cache: dict[str, bytes | None] = {}
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
    images: dict[str, bytes | None],
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
