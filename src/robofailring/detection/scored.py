"""The frames a detector run decodes and scores of a trajectory: shared by `FailureDetector.run` and the
jobs that encode those frames ahead of it (`CachedEncoder.prefetch`, docs/ray.md)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robofailring.data.model import Frame, Skipped, Trajectory
from robofailring.detection.config import DEFAULT_STRIDE
from robofailring.encoders.base import BLANK_REASON, frame_ranges
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import DataError


@dataclass(frozen=True)
class ScoredFrames:
    """The views scored (those of ≥ 2 frames, in the trajectory's order), the shortest one's length, the
    frame numbers scored in each (0, stride, 2·stride, … below that length) and the views left out (too
    short)."""

    views: dict[str, Sequence[Frame]]
    length: int
    steps: np.ndarray
    short_views: list[str]

    def frames(self) -> list[Frame]:
        """Every frame scored, view by view."""
        return [frames[int(t)] for frames in self.views.values() for t in self.steps]


def scored_frames(trajectory: Trajectory, *, stride: int = DEFAULT_STRIDE) -> ScoredFrames:
    """What a run over `trajectory` at `stride` scores; DataError when no view has 2 frames."""
    used = {view: frames for view, frames in trajectory.views.items() if len(frames) >= 2}
    if not used:
        raise DataError(
            f"trajectory {trajectory.key} ({trajectory.source}) has no view with at least 2 frames"
        )
    length = min(len(frames) for frames in used.values())
    short = [v for v in trajectory.views if v not in used]
    return ScoredFrames(used, length, np.arange(0, length, stride), short)


def prefetch_scored(
    encoder: CachedEncoder, trajectories: Iterable[Trajectory], *, stride: int = DEFAULT_STRIDE
) -> None:
    """Hand an encoder that works ahead (`--ray`) every frame runs over `trajectories` at `stride` will
    score, to encode in one pass (`CachedEncoder.prefetch`: nothing is listed for one that encodes on
    demand). A run with no view of 2 frames is left for its own run to report."""
    encoder.prefetch(_frames_scored(trajectories, stride=stride))


def _frames_scored(trajectories: Iterable[Trajectory], *, stride: int) -> Iterator[Frame]:
    for trajectory in trajectories:
        try:
            scored = scored_frames(trajectory, stride=stride)
        except DataError:
            continue
        yield from scored.frames()


def blank_skips(trajectory: Trajectory, blank: Mapping[str, Sequence[int]], scored: int) -> list[Skipped]:
    """Each view's frames the encoder saw as nothing (`blank`: their numbers), as inputs not scored: a
    camera that goes dark is said, never passed as `no alarm`; a blank first frame leaves its view unscored."""
    where = trajectory.source or Path(trajectory.key)
    found = []
    for view, frames in blank.items():
        if not frames:
            continue
        what = (
            f"its first frame is {BLANK_REASON}: the view is not scored"
            if frames[0] == 0
            else f"{len(frames)} of {scored} scored frame(s) ({frame_ranges(frames)}) are {BLANK_REASON} "
            "(a camera gone dark?)"
        )
        found.append(Skipped(where, f"{trajectory.key} view {view}: {what}", view))
    return found
