"""One episode scored for triage: its score curve, its peak (frame and view), the nearest failure and
the nearest normal frame there; a summary small enough to keep for every episode of a large dataset."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from robofailring.data.model import Frame, Skipped, Trajectory
from robofailring.detection.detector import FailureDetector
from robofailring.errors import DataError


@dataclass(frozen=True)
class EpisodeScore:
    """What triage says about one episode (`rank` and `rank_score` are set by `ranking.rank`)."""

    task: str
    episode: str
    mode: str  # the reference its task is judged against (robofailring.triage.reference)
    rule: str  # the scoring rule: paper, contrast or novelty
    threshold: float  # the rule's threshold (calibrated with a memory, else the rule's default)
    curve: np.ndarray = field(repr=False)  # per frame: the rule's score, max over views (NaN: not scored)
    peak: float = float("nan")  # the curve's highest value (NaN: nothing scored)
    frame: int = -1  # the peak's frame
    view: str = ""  # the view scoring highest at the peak
    thumbnail: Frame | None = field(default=None, repr=False)  # that view's frame at the peak
    source: Path | None = None  # the episode's folder or file
    length: int = 0
    failure_symbol: str = ""  # the nearest failure entry at the peak (a memory with failures of the task)
    failure_description: str = ""  # its grounded sentence
    failure_episode: str = ""
    normal_episode: str = ""  # the nearest success-memory frame at the peak: episode, frame, image
    normal_frame: int = -1
    normal_image: str = ""
    skipped: tuple[Skipped, ...] = ()  # views not scored (fewer than 2 frames), or the whole episode
    rank_score: float = float("nan")  # what the ranking orders by (robofailring.triage.ranking)
    rank: int = 0  # 1 for the episode least like normal runs

    @property
    def key(self) -> str:
        return f"{self.task}/{self.episode}"

    @property
    def scored(self) -> bool:
        return bool(np.isfinite(self.peak))


def score_episode(detector: FailureDetector, trajectory: Trajectory, *, mode: str) -> EpisodeScore:
    """Score `trajectory` with its own episode left out of the memory (it may be one of its runs).

    An episode with no view of 2 frames is not scored: its score says so (`skipped`), it ranks last.
    """
    rule = detector.rule_for(trajectory.task)
    base = EpisodeScore(
        task=trajectory.task,
        episode=trajectory.episode,
        mode=mode,
        rule=rule.name,
        threshold=float(detector.threshold_of(rule)),
        curve=np.zeros(0, np.float32),
        source=trajectory.source,
    )
    try:
        trace = detector.run(trajectory, leave_one_out=True, keep_queries=False)
    except DataError as error:
        return replace(
            base, skipped=(Skipped(trajectory.source or Path(trajectory.key), f"not scored: {error}"),)
        )
    judged = trace.judged_scores_of(trace.rule)
    fused = trace.max_score()
    curve = np.where(np.isfinite(fused), fused, np.nan).astype(np.float32)
    base = replace(
        base,
        threshold=float(trace.threshold),
        curve=curve,
        length=trace.length,
        skipped=tuple(trace.short_views),
    )
    if not np.isfinite(curve).any():  # e.g. the only run of its task, or the memory's only failure of it
        why = (
            f"not scored: with its own episode left out, the memory holds nothing of task {trajectory.task!r} "
            f"the {rule.name} rule compares with"
        )
        return replace(base, skipped=(*base.skipped, Skipped(trajectory.source or Path(trajectory.key), why)))
    frame = int(np.nanargmax(curve))
    view = max(  # a camera: the peak's thumbnail (its signals, when they fired, are not an image)
        trace.views,
        key=lambda v: float(np.nan_to_num(judged[v][frame], nan=-np.inf)) if v in judged else -np.inf,
    )
    nearest = trace.neighbors(view, frame)
    normal = trace.nearest_success(view, frame)
    return replace(
        base,
        peak=float(curve[frame]),
        frame=frame,
        view=view,
        thumbnail=trajectory.views[view][frame],
        failure_symbol=nearest[0].entry.symbol if nearest else "",
        failure_description=nearest[0].entry.description if nearest else "",
        failure_episode=nearest[0].entry.episode if nearest else "",
        normal_episode=normal.run.episode if normal is not None else "",
        normal_frame=normal.frame if normal is not None else -1,
        normal_image=normal.image if normal is not None else "",
    )
