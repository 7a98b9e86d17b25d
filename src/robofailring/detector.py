"""The streaming failure detector (paper §3.3, eq. 4–7): S_t per view, fused over views."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Final, Protocol

import numpy as np

from robofailring.data.images import as_rgb
from robofailring.data.model import Frame, Skipped, Trajectory
from robofailring.encoders.base import Encoder, l2_normalize
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import DataError, SettingError
from robofailring.memory import FailureMemory, Neighbor, pair_vectors

PAPER_DELTA: Final[float] = 0.92
DEFAULT_K: Final[int] = 5


@dataclass(frozen=True)
class StepResult:
    """What the detector says about one time step."""

    t: int
    similarity: dict[str, float]
    neighbors: dict[str, list[Neighbor]]
    state: bool
    fired_views: list[str]
    queries: dict[str, np.ndarray] = field(default_factory=dict, repr=False)  # (f(I_0) ‖ f(I_t)) per view


class StepSink(Protocol):
    """Receives every step of a live session, e.g. `rfr_viz.LiveRecording` streams it to a Rerun viewer."""

    def on_step(
        self, session: DetectorSession, frames: Mapping[str, np.ndarray | Frame], result: StepResult
    ) -> None: ...


@dataclass
class DetectionTrace:
    """A whole replayed trajectory: S_t per view per frame, neighbours, t_det and L."""

    task: str
    episode: str
    length: int
    delta: float
    k: int
    encoder: str
    views: list[str]
    similarity: dict[str, np.ndarray]
    neighbor_ids: dict[str, np.ndarray]
    neighbor_similarity: dict[str, np.ndarray]
    queries: dict[str, np.ndarray] = field(repr=False)  # one row per scored frame
    memory: FailureMemory = field(repr=False)
    skipped_views: list[str] = field(default_factory=list)
    view_frames: dict[str, int] = field(default_factory=dict)  # frames each view had (L bounds them)
    stride: int = 1  # every `stride`-th frame from frame 0 is scored; the others hold NaN / -1
    skipped_inputs: list[Skipped] = field(default_factory=list)  # files of the episode not read

    @property
    def scored_frames(self) -> np.ndarray:
        """Indices (original frame numbers) of the frames that were scored: 0, stride, 2·stride, …"""
        return np.arange(0, self.length, self.stride)

    @property
    def truncated_views(self) -> dict[str, int]:
        """Views longer than L (the shortest used view) and how many of their frames were not scored."""
        return {view: count - self.length for view, count in self.view_frames.items() if count > self.length}

    @property
    def state(self) -> np.ndarray:
        """State_t (eq. 7) fused over views: 1 where any view's S_t ≥ δ."""
        if not self.views:
            return np.zeros(self.length, dtype=bool)
        stacked = np.stack([np.nan_to_num(self.similarity[v], nan=-np.inf) for v in self.views])
        return np.asarray((stacked >= self.delta).any(axis=0))

    @property
    def t_det(self) -> int | None:
        """The first frame at which the detector fires, or None."""
        fired = np.flatnonzero(self.state)
        return int(fired[0]) if fired.size else None

    @property
    def detected(self) -> bool:
        return self.t_det is not None

    @property
    def detected_view(self) -> str | None:
        """The view with the highest S_t among those over δ at t_det."""
        t = self.t_det
        if t is None:
            return None
        return max(self.views, key=lambda v: np.nan_to_num(self.similarity[v][t], nan=-np.inf))

    def max_similarity(self) -> np.ndarray:
        """max over views of S_t, per frame."""
        stacked = np.stack([np.nan_to_num(self.similarity[v], nan=-np.inf) for v in self.views])
        return stacked.max(axis=0)

    def neighbors(self, view: str, t: int) -> list[Neighbor]:
        return self.memory.neighbors(self.neighbor_similarity[view][t], self.neighbor_ids[view][t])

    def with_delta(self, delta: float) -> DetectionTrace:
        """The same trace judged at another threshold (S_t does not depend on δ)."""
        return DetectionTrace(**{**self.__dict__, "delta": delta})

    def to_dict(self) -> dict[str, Any]:
        """The JSON shape of `robofailring detect --json`."""
        views: dict[str, Any] = {}
        for view in self.views:
            top = []
            for t in range(self.length):
                found = self.neighbors(view, t)
                top.append(
                    None
                    if not found
                    else {
                        "task": found[0].entry.task,
                        "symbol": found[0].entry.symbol,
                        "view": found[0].entry.view,
                        "episode": found[0].entry.episode,
                        "similarity": round(found[0].similarity, 6),
                    }
                )
            views[view] = {
                "similarity": [None if np.isnan(s) else round(float(s), 6) for s in self.similarity[view]],
                "top_neighbor": top,
            }
        return {
            "task": self.task,
            "episode": self.episode,
            "length": self.length,
            "delta": self.delta,
            "k": self.k,
            "encoder": self.encoder,
            "t_det": self.t_det,
            "detected_view": self.detected_view,
            "skipped_views": self.skipped_views,
            "unscored_frames": self.truncated_views,
            "stride": self.stride,
            "skipped_inputs": [skipped.to_dict() for skipped in self.skipped_inputs],
            "views": views,
        }


def check_k(k: int) -> int:
    """K, the neighbours retrieved per query: at least 1 (SettingError otherwise)."""
    if k < 1:
        raise SettingError(f"k (neighbours per query) must be at least 1, got {k}")
    return k


def check_stride(stride: int) -> int:
    """The scoring stride: at least 1 (SettingError otherwise)."""
    if stride < 1:
        raise SettingError(f"stride must be at least 1 (1 scores every frame), got {stride}")
    return stride


def check_delta(delta: float) -> float:
    """δ: a cosine similarity threshold, so within [-1, 1] (SettingError otherwise)."""
    if not -1.0 <= delta <= 1.0:  # also rejects NaN
        raise SettingError(f"δ must lie in [-1, 1] (S_t is a cosine similarity), got {delta}")
    return delta


class FailureDetector:
    """Matches (first frame ‖ current frame) queries against one task's failure memory."""

    def __init__(
        self,
        memory: FailureMemory,
        encoder: Encoder | CachedEncoder,
        *,
        delta: float | None = None,
        k: int = DEFAULT_K,
    ) -> None:
        memory.check_encoder(encoder.identity)
        check_k(k)
        if delta is not None:
            check_delta(delta)
        self.memory = memory
        self.encoder = (
            encoder if isinstance(encoder, CachedEncoder) else CachedEncoder(encoder, enabled=False)
        )
        calibrated = memory.calibrated_delta
        self.delta = float(
            delta if delta is not None else calibrated if calibrated is not None else PAPER_DELTA
        )
        self.k = k

    def session(
        self, task: str, *, exclude_episode: str | None = None, sink: StepSink | None = None
    ) -> DetectorSession:
        """A live session for a robot: feed each step's frames with `step`; `sink` sees every step."""
        self.memory.task_size(task)  # unknown task -> clear error before the robot moves
        return DetectorSession(self, task, exclude_episode=exclude_episode, sink=sink)

    def run(self, trajectory: Trajectory, *, leave_one_out: bool = False, stride: int = 1) -> DetectionTrace:
        """Detect over a whole trajectory; `leave_one_out` hides its own episode's memory entries.

        With `stride` N only frames 0, N, 2N, … are decoded and scored (I_0 stays frame 0); the
        trace keeps original frame numbers (t_det, L), unscored frames hold NaN.
        """
        check_stride(stride)
        self.memory.task_size(trajectory.task)
        used = {view: frames for view, frames in trajectory.views.items() if len(frames) >= 2}
        skipped = [view for view in trajectory.views if view not in used]
        if not used:
            raise DataError(
                f"trajectory {trajectory.key} ({trajectory.source}) has no view with at least 2 frames"
            )
        length = min(len(frames) for frames in used.values())
        views = list(used)
        steps = np.arange(0, length, stride)
        frames = [used[view][int(t)] for view in views for t in steps]
        embeddings = self.encoder.encode_frames(frames).reshape(len(views), len(steps), -1)
        exclude = trajectory.episode if leave_one_out else None
        similarity, ids, sims, queries = {}, {}, {}, {}
        for position, view in enumerate(views):
            view_embeddings = embeddings[position]
            query = pair_vectors(np.repeat(view_embeddings[:1], len(steps), axis=0), view_embeddings)
            top_sims, top_ids = self.memory.search(query, trajectory.task, self.k, exclude_episode=exclude)
            if stride > 1:  # back onto original frame numbers: unscored frames never fire
                full_sims = np.full((length, self.k), np.nan, dtype=top_sims.dtype)
                full_ids = np.full((length, self.k), -1, dtype=top_ids.dtype)
                full_sims[steps], full_ids[steps] = top_sims, top_ids
                top_sims, top_ids = full_sims, full_ids
            similarity[view] = top_sims[:, 0].copy()
            ids[view], sims[view], queries[view] = top_ids, top_sims, query
        return DetectionTrace(
            task=trajectory.task,
            episode=trajectory.episode,
            length=length,
            delta=self.delta,
            k=self.k,
            encoder=self.encoder.identity,
            views=views,
            similarity=similarity,
            neighbor_ids=ids,
            neighbor_similarity=sims,
            queries=queries,
            memory=self.memory,
            skipped_views=skipped,
            view_frames={view: len(frames) for view, frames in trajectory.views.items()},
            stride=stride,
            skipped_inputs=list(trajectory.skipped),
        )


class DetectorSession:
    """Per-episode state of the step API: the first frame of every view and the step counter."""

    def __init__(
        self,
        detector: FailureDetector,
        task: str,
        *,
        exclude_episode: str | None,
        sink: StepSink | None = None,
    ) -> None:
        self.detector = detector
        self.task = task
        self.exclude_episode = exclude_episode
        self.sink = sink
        self._first: dict[str, np.ndarray] = {}
        self.t = 0
        self.fired_at: int | None = None

    def step(self, frames: Mapping[str, np.ndarray | Frame]) -> StepResult:
        """Feed the current frame of each view; the first call also fixes I_0 per view."""
        views = list(frames)
        values = list(frames.values())
        if all(isinstance(f, Frame) for f in values):
            embeddings = self.detector.encoder.encode_frames([f for f in values if isinstance(f, Frame)])
        else:  # live frames are new every step: no cache round trip
            images = [
                f.load() if isinstance(f, Frame) else as_rgb(f, source=f"view {v}") for v, f in frames.items()
            ]
            embeddings = l2_normalize(self.detector.encoder.encoder.encode(images))
        similarity: dict[str, float] = {}
        neighbors: dict[str, list[Neighbor]] = {}
        queries: dict[str, np.ndarray] = {}
        for view, embedding in zip(views, embeddings, strict=True):
            first = self._first.setdefault(view, embedding)
            query = queries[view] = pair_vectors(first, embedding)
            sims, ids = self.detector.memory.search(
                query, self.task, self.detector.k, exclude_episode=self.exclude_episode
            )
            similarity[view] = float(sims[0, 0])
            neighbors[view] = self.detector.memory.neighbors(sims[0], ids[0])
        fired = [v for v in views if similarity[v] >= self.detector.delta]
        result = StepResult(
            t=self.t,
            similarity=similarity,
            neighbors=neighbors,
            state=bool(fired),
            fired_views=fired,
            queries=queries,
        )
        if fired and self.fired_at is None:
            self.fired_at = self.t
        if self.sink is not None:
            self.sink.on_step(self, frames, result)
        self.t += 1
        return result
