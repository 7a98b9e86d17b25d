"""The streaming failure detector (paper §3.3, eq. 4–7): S_t per view, fused over views."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final, Protocol

import numpy as np

from robofailring.data.images import as_rgb
from robofailring.data.model import Frame, Trajectory
from robofailring.detection.rules import DEFAULT_GAMMA, PAPER_DELTA, ScoreRule, check_threshold
from robofailring.detection.trace import DetectionTrace, StepResult
from robofailring.encoders.base import Encoder, l2_normalize
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import DataError, SettingError
from robofailring.memory.failure import FailureMemory, Neighbor
from robofailring.memory.pairs import pair_vectors
from robofailring.memory.success import SuccessMatch

DEFAULT_K: Final[int] = 5


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


class StepSink(Protocol):
    """Receives every step of a live session, e.g. `rfr_viz.LiveRecording` streams it to a Rerun viewer."""

    def on_step(
        self, session: DetectorSession, frames: Mapping[str, np.ndarray | Frame], result: StepResult
    ) -> None: ...


class FailureDetector:
    """Matches (first frame ‖ current frame) queries against one task's failure memory."""

    def __init__(
        self,
        memory: FailureMemory,
        encoder: Encoder | CachedEncoder,
        *,
        delta: float | None = None,
        k: int = DEFAULT_K,
        rule: ScoreRule | str | None = None,
        gamma: float | None = None,
    ) -> None:
        memory.check_encoder(encoder.identity)
        check_k(k)
        if delta is not None:
            check_delta(delta)
        if gamma is not None:
            check_threshold(ScoreRule.CONTRAST, gamma)
        self.rule = default_rule(memory) if rule is None else ScoreRule.parse(rule)
        if self.rule is ScoreRule.CONTRAST and memory.successes is None:
            raise SettingError(
                "the contrast rule needs success runs in the memory, and this one has none (built with "
                "--no-successes or before success contrast existed); use --score paper or rebuild the memory"
            )
        self.memory = memory
        self.encoder = (
            encoder if isinstance(encoder, CachedEncoder) else CachedEncoder(encoder, enabled=False)
        )
        calibrated = memory.calibrated_delta
        self.delta = float(
            delta if delta is not None else calibrated if calibrated is not None else PAPER_DELTA
        )
        calibrated_gamma = memory.calibrated_gamma
        self.gamma = float(
            gamma
            if gamma is not None
            else calibrated_gamma
            if calibrated_gamma is not None
            else DEFAULT_GAMMA
        )
        self.k = k

    @property
    def threshold(self) -> float:
        """δ (paper rule) or γ (contrast rule)."""
        return self.delta if self.rule is ScoreRule.PAPER else self.gamma

    def _check_task(self, task: str) -> None:
        """Unknown task, or a contrast rule for a task without success runs: a clear error up front."""
        self.memory.task_size(task)
        successes = self.memory.successes
        if self.rule is ScoreRule.CONTRAST and successes is not None and not successes.has_task(task):
            raise SettingError(
                f"task {task!r} has no success runs in the memory, so the contrast rule cannot judge it; "
                "use --score paper or add success runs of this task"
            )

    def success_search(
        self, queries: np.ndarray, task: str, exclude: str | None
    ) -> tuple[np.ndarray, np.ndarray] | None:
        successes = self.memory.successes
        if successes is None:
            return None
        return successes.search(queries, task, exclude_episode=exclude)

    def session(
        self, task: str, *, exclude_episode: str | None = None, sink: StepSink | None = None
    ) -> DetectorSession:
        """A live session for a robot: feed each step's frames with `step`; `sink` sees every step."""
        self._check_task(task)  # unknown task -> clear error before the robot moves
        return DetectorSession(self, task, exclude_episode=exclude_episode, sink=sink)

    def run(self, trajectory: Trajectory, *, leave_one_out: bool = False, stride: int = 1) -> DetectionTrace:
        """Detect over a whole trajectory; `leave_one_out` hides its own episode from both memories.

        With `stride` N only frames 0, N, 2N, … are decoded and scored (I_0 stays frame 0); the
        trace keeps original frame numbers (t_det, L), unscored frames hold NaN.
        """
        check_stride(stride)
        self._check_task(trajectory.task)
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
        success_similarity, success_ids = {}, {}
        for position, view in enumerate(views):
            view_embeddings = embeddings[position]
            queries[view] = pair_vectors(np.repeat(view_embeddings[:1], len(steps), axis=0), view_embeddings)
        stacked = np.concatenate([queries[view] for view in views])  # one search per memory, all views
        all_sims, all_ids = self.memory.search(stacked, trajectory.task, self.k, exclude_episode=exclude)
        all_success = self.success_search(stacked, trajectory.task, exclude)
        for position, view in enumerate(views):
            rows = slice(position * len(steps), (position + 1) * len(steps))
            query = queries[view]
            top_sims, top_ids = all_sims[rows], all_ids[rows]
            if stride > 1:  # back onto original frame numbers: unscored frames never fire
                full_sims = np.full((length, self.k), np.nan, dtype=top_sims.dtype)
                full_ids = np.full((length, self.k), -1, dtype=top_ids.dtype)
                full_sims[steps], full_ids[steps] = top_sims, top_ids
                top_sims, top_ids = full_sims, full_ids
            similarity[view] = top_sims[:, 0].copy()
            ids[view], sims[view], queries[view] = top_ids, top_sims, query
            if all_success is not None:
                success_sims, success_rows = all_success[0][rows], all_success[1][rows]
                if stride > 1:  # as above: S⁺ only at scored frames
                    full_success = np.full(length, np.nan, dtype=success_sims.dtype)
                    full_rows = np.full(length, -1, dtype=success_rows.dtype)
                    full_success[steps], full_rows[steps] = success_sims, success_rows
                    success_sims, success_rows = full_success, full_rows
                success_similarity[view], success_ids[view] = success_sims, success_rows
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
            rule=self.rule,
            gamma=self.gamma,
            success_similarity=success_similarity,
            success_ids=success_ids,
        )


def default_rule(memory: FailureMemory) -> ScoreRule:
    """`contrast` when the memory holds success runs, else the paper's rule."""
    return ScoreRule.CONTRAST if memory.successes is not None else ScoreRule.PAPER


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
        success: dict[str, float] = {}
        nearest: dict[str, SuccessMatch | None] = {}
        neighbors: dict[str, list[Neighbor]] = {}
        queries: dict[str, np.ndarray] = {}
        for view, embedding in zip(views, embeddings, strict=True):
            first = self._first.setdefault(view, embedding)
            queries[view] = pair_vectors(first, embedding)[0]
        stacked = np.stack([queries[view] for view in views])  # one search per memory for all views
        sims, ids = self.detector.memory.search(
            stacked, self.task, self.detector.k, exclude_episode=self.exclude_episode
        )
        found = self.detector.success_search(stacked, self.task, self.exclude_episode)
        successes = self.detector.memory.successes
        for row, view in enumerate(views):
            similarity[view] = float(sims[row, 0])
            neighbors[view] = self.detector.memory.neighbors(sims[row], ids[row])
            success[view] = float(found[0][row]) if found is not None else float("nan")
            if found is not None and successes is not None:
                nearest[view] = successes.match(success[view], int(found[1][row]))
        contrasts = {v: similarity[v] - success[v] for v in views}
        rule, threshold = self.detector.rule, self.detector.threshold
        scores = similarity if rule is ScoreRule.PAPER else contrasts
        fired = [v for v in views if scores[v] >= threshold]  # NaN never fires
        result = StepResult(
            t=self.t,
            similarity=similarity,
            neighbors=neighbors,
            state=bool(fired),
            fired_views=fired,
            queries=queries,
            success_similarity=success,
            nearest_success=nearest,
            contrast=contrasts,
            rule=rule,
            threshold=threshold,
        )
        if fired and self.fired_at is None:
            self.fired_at = self.t
        if self.sink is not None:
            self.sink.on_step(self, frames, result)
        self.t += 1
        return result
