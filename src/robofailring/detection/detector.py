"""The streaming failure detector (paper §3.3, eq. 4–7): S_t per view, fused over views."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Final

import numpy as np

from robofailring.data.images import as_rgb
from robofailring.data.model import Frame, Skipped, Trajectory
from robofailring.detection.band import Band
from robofailring.detection.config import (
    DEFAULT_K,
    DEFAULT_MODALITY,
    DEFAULT_STRIDE,
    check_k,
    check_modality,
    check_stride,
)
from robofailring.detection.retrieved import Retrieved
from robofailring.detection.rules import (
    RuleThresholds,
    ScoringRule,
    default_rule,
    rule_named,
)
from robofailring.detection.scored import blank_skips, scored_frames
from robofailring.detection.session import DetectorSession, StepSink
from robofailring.detection.signal_scores import SignalScores, score_signals
from robofailring.detection.stored import (
    given_thresholds,
    stored_bands,
    stored_thresholds,
    uncalibrated_notes,
)
from robofailring.detection.trace import DetectionTrace
from robofailring.encoders.base import Encoder, l2_normalize, unusable
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import DataError, SettingError
from robofailring.memory.failure import FailureMemory
from robofailring.memory.references import absolute_reference
from robofailring.memory.signals.modality import BOTH, SIGNALS, SIGNALS_VIEW

CHUNK_FRAMES: Final[int] = 256  # scored frames per view encoded and searched at once in `run`

Place = Callable[[str, np.ndarray], np.ndarray]  # (view, (n, 2d) queries) -> (n, m) rows, e.g. map points


class FailureDetector(RuleThresholds):
    """Matches (first frame ‖ current frame) queries against one task's failure memory.

    It judges by one scoring rule (`robofailring.detection.rules`) at that rule's threshold: the
    one given for every task, else each task's default (`rule_for`: contrast with success and
    failure runs, novelty with success runs only, paper with failures only). The threshold of
    every registered rule comes from `thresholds` (by rule name; `delta`/`gamma`/`eta` are the
    paper, contrast and novelty rules' there) when given, else the memory's stored calibration,
    else the rule's default. A stored threshold comes with its time-indexed band when it was calibrated
    with one (`robofailring.detection.band`); `bands` replaces those (e.g. thresholds calibrated in
    process by the evaluation). A threshold given here is one number, without a band.
    """

    def __init__(
        self,
        memory: FailureMemory,
        encoder: Encoder | CachedEncoder,
        *,
        thresholds: Mapping[str, float] | None = None,
        delta: float | None = None,
        k: int = DEFAULT_K,
        rule: ScoringRule | str | None = None,
        gamma: float | None = None,
        eta: float | None = None,
        bands: Mapping[str, Band] | None = None,
        modality: str = DEFAULT_MODALITY,
    ) -> None:
        memory.check_encoder(encoder.identity)
        check_k(k)
        if check_modality(modality) == SIGNALS and memory.signals is None:
            raise SettingError(
                "--modality signals needs a memory with the robot's signals, and this one has none (built from "
                "data without signals, or with --signals none)"
            )
        self.modality = modality if memory.signals is not None else BOTH  # no signals: the cameras are all
        given = given_thresholds(thresholds, delta=delta, gamma=gamma, eta=eta)
        self.thresholds = stored_thresholds(memory, given, self.modality)
        self.bands: dict[str, Band] = (  # per rule name: the band its threshold applies to
            dict(bands)
            if bands is not None
            else {
                name: band for name, band in stored_bands(memory, self.modality).items() if name not in given
            }
        )
        self.chosen_rule = rule_named(rule) if rule is not None else None  # None: each task's default
        self.memory = memory
        if self.rule.needs_successes and memory.successes is None:
            raise SettingError(
                f"the {self.rule.name} rule needs success runs in the memory, and this one has none (built with "
                "--no-successes or before success contrast existed); use --score paper or rebuild the memory"
            )
        if self.rule.needs_failures and not len(memory):
            raise SettingError(
                f"the {self.rule.name} rule needs failure runs in the memory, and this one has none (built from "
                "success runs only); use --score novelty or add failure runs"
            )
        self.encoder = (
            encoder if isinstance(encoder, CachedEncoder) else CachedEncoder(encoder, enabled=False)
        )
        self.k = k
        used = (
            [self.chosen_rule] if self.chosen_rule is not None else [self.rule_for(t) for t in memory.tasks]
        )
        self.uncalibrated = uncalibrated_notes(
            memory, given, used, self.modality
        )  # said by the jobs that detect

    @property
    def rule(self) -> ScoringRule:
        """The rule given, else the memory's default as a whole (`default_rule` over all its tasks)."""
        if self.chosen_rule is not None:
            return self.chosen_rule
        return default_rule(successes=self.memory.successes is not None, failures=len(self.memory) > 0)

    def rule_for(self, task: str) -> ScoringRule:
        """The rule `task` is judged by: the one given, else the task's default (what its memory holds)."""
        if self.chosen_rule is not None:
            return self.chosen_rule
        successes = self.memory.successes
        return default_rule(
            successes=successes is not None and successes.has_task(task),
            failures=self.memory.has_failures(task),
        )

    @property
    def threshold(self) -> float:
        """The rule's threshold: δ (paper rule), γ (contrast rule), η (novelty rule), …"""
        return self.threshold_of(self.rule)

    def _check_task(self, task: str) -> ScoringRule:
        """The task's rule; unknown task, or a rule needing runs the task lacks: a clear error up front."""
        self.memory.task_size(task)
        rule = self.rule_for(task)
        successes = self.memory.successes
        if rule.needs_successes and successes is not None and not successes.has_task(task):
            raise SettingError(
                f"task {task!r} has no success runs in the memory, so the {rule.name} rule cannot judge it; "
                "use --score paper or add success runs of this task"
            )
        if rule.needs_failures and not self.memory.has_failures(task):
            raise SettingError(
                f"task {task!r} has no failure runs in the memory, so the {rule.name} rule cannot judge it; "
                "use --score novelty (or leave --score out) or add failure runs of this task"
            )
        return rule

    def encode(self, frames: Sequence[np.ndarray | Frame], views: Sequence[str]) -> np.ndarray:
        """Unit-norm embeddings of `frames` (one per view name in `views`, for error messages).

        Frames from files go through the encoder's cache; live arrays are new every step, so they do not."""
        if all(isinstance(f, Frame) for f in frames):
            return self.encoder.encode_frames([f for f in frames if isinstance(f, Frame)])
        images = [
            f.load() if isinstance(f, Frame) else as_rgb(f, source=f"view {v}")
            for v, f in zip(views, frames, strict=True)
        ]
        return l2_normalize(self.encoder.encoder.encode(images))

    def retrieve(
        self,
        task: str,
        first: Mapping[str, np.ndarray],
        current: Mapping[str, np.ndarray],
        *,
        exclude_episode: str | None = None,
    ) -> Retrieved:
        """The batched core of `run` and `step`: pair queries, one search per memory for all views and frames.

        `first` holds f(I_0) per view, `current` the (T, d) embeddings of T frames per view.
        """
        views = list(current)
        blank = {  # a frame the encoder sees as nothing (zero, or not a number) matches nothing
            view: unusable(current[view]) | bool(unusable(first[view][None])[0]) for view in views
        }
        current = {
            view: np.where(blank[view][:, None], 0.0, current[view]).astype(np.float32) for view in views
        }
        first = {view: np.nan_to_num(first[view], nan=0.0, posinf=0.0, neginf=0.0) for view in views}
        queries = {view: self.memory.pair(first[view], current[view]) for view in views}  # as its entries
        stacked = np.concatenate([queries[view] for view in views])
        sims, ids = self.memory.search(stacked, task, self.k, exclude_episode=exclude_episode)
        bounds = np.cumsum([0] + [len(queries[view]) for view in views])
        rows = {view: slice(int(bounds[i]), int(bounds[i + 1])) for i, view in enumerate(views)}
        success_similarity: dict[str, np.ndarray] = {}
        success_ids: dict[str, np.ndarray] = {}
        successes = self.memory.successes
        if successes is not None:
            success_sims, success_rows = successes.search(stacked, task, exclude_episode=exclude_episode)
            success_similarity = {view: success_sims[rows[view]] for view in views}
            success_ids = {view: success_rows[rows[view]] for view in views}
        return Retrieved(
            queries=queries,
            neighbor_similarity={view: sims[rows[view]] for view in views},
            neighbor_ids={view: ids[rows[view]] for view in views},
            success_similarity=success_similarity,
            success_ids=success_ids,
        ).without_blank(blank)

    def session(
        self, task: str, *, exclude_episode: str | None = None, sink: StepSink | None = None
    ) -> DetectorSession:
        """A live session for a robot: feed each step's frames with `step`; `sink` sees every step."""
        rule = self._check_task(task)  # unknown task -> clear error before the robot moves
        return DetectorSession(self, task, rule, exclude_episode=exclude_episode, sink=sink)

    def run(
        self,
        trajectory: Trajectory,
        *,
        leave_one_out: bool = False,
        stride: int = DEFAULT_STRIDE,
        keep_queries: bool = True,
        place: Place | None = None,
    ) -> DetectionTrace:
        """Detect over a whole trajectory; `leave_one_out` hides its own episode from both memories.

        With `stride` N only frames 0, N, 2N, … are decoded and scored (I_0 stays frame 0); the
        trace keeps original frame numbers (t_det, L), unscored frames hold NaN.

        Frames are encoded and searched CHUNK_FRAMES at a time. The (f(I_0) ‖ f(I_t)) queries, as
        large as the frames' embeddings, are kept in `trace.queries`; with `keep_queries=False` they
        are not, and memory does not grow with the episode beyond its per-frame scores.
        `place(view, queries)` reduces each chunk's queries to the rows kept in `trace.placed` (e.g.
        points of a 2-D map), so a recording needs no queries either.
        """
        check_stride(stride)
        rule = self._check_task(trajectory.task)
        scored = scored_frames(trajectory, stride=stride)
        used, steps, skipped, length = scored.views, scored.steps, scored.short_views, scored.length
        views = list(used)
        exclude = trajectory.episode if leave_one_out else None
        first: dict[str, np.ndarray] = {}
        parts: list[Retrieved] = []
        placed: dict[str, list[np.ndarray]] = {view: [] for view in views}
        blank: dict[str, list[int]] = {view: [] for view in views}  # frames the encoder saw as nothing
        for start in range(0, len(steps), CHUNK_FRAMES):
            chunk = steps[start : start + CHUNK_FRAMES]
            frames = [used[view][int(t)] for view in views for t in chunk]
            embeddings = self.encode(frames, [view for view in views for _ in chunk]).reshape(
                len(views), len(chunk), -1
            )
            current = {view: embeddings[position] for position, view in enumerate(views)}
            first = first or {view: current[view][0] for view in views}
            for view in views:
                blank[view] += chunk[unusable(current[view])].tolist()
            part = self.retrieve(trajectory.task, first, current, exclude_episode=exclude)
            if place is not None:
                for view in views:
                    placed[view].append(np.asarray(place(view, part.queries[view])))
            parts.append(part if keep_queries else part.without_queries())
        found = Retrieved.joined(parts)

        def on_frames(values: np.ndarray, fill: float) -> np.ndarray:
            """Scored rows back onto original frame numbers: unscored frames never fire."""
            if stride == 1:
                return values
            full = np.full((length, *values.shape[1:]), fill, dtype=values.dtype)
            full[steps] = values
            return full

        neighbor_similarity = {view: on_frames(found.neighbor_similarity[view], np.nan) for view in views}
        signals, unscored = self._signal_scores(trajectory, steps, length, exclude)
        own = self.memory.own_episode(
            trajectory.task,
            (absolute_reference(used[view][0].reference) for view in views),
            exclude_episode=exclude,
        )
        return DetectionTrace(
            task=trajectory.task,
            episode=trajectory.episode,
            length=length,
            rule=rule,
            thresholds=dict(self.thresholds),
            k=self.k,
            encoder=self.encoder.identity,
            views=views,
            similarity={view: neighbor_similarity[view][:, 0].copy() for view in views},
            neighbor_ids={view: on_frames(found.neighbor_ids[view], -1) for view in views},
            neighbor_similarity=neighbor_similarity,
            queries=found.queries,
            placed={view: np.concatenate(rows) for view, rows in placed.items()} if place is not None else {},
            memory=self.memory,
            skipped_views=skipped,
            view_frames={view: len(frames) for view, frames in trajectory.views.items()},
            stride=stride,
            skipped_inputs=[*trajectory.skipped, *blank_skips(trajectory, blank, len(steps)), *unscored],
            success_similarity={v: on_frames(s, np.nan) for v, s in found.success_similarity.items()},
            success_ids={v: on_frames(i, -1) for v, i in found.success_ids.items()},
            in_memory=own is not None,
            bands={name: band.for_task(trajectory.task) for name, band in self.bands.items()},
            source=trajectory.source,
            signals=signals,
            modality=self.modality,
            cameras_alone=self.memory.signals is not None
            and self.memory.signals.task(trajectory.task) is not None
            and not trajectory.signals,
        )

    def _signal_scores(
        self, trajectory: Trajectory, steps: np.ndarray, length: int, exclude: str | None
    ) -> tuple[SignalScores | None, list[Skipped]]:
        """The signal modality's scores where the memory has signals of the task; a run whose signals
        cannot be read is scored by its cameras alone and listed as such."""
        task = self.memory.signals.task(trajectory.task) if self.memory.signals is not None else None
        if task is None or not trajectory.signals:  # a run that records no signals: the trace notes it
            return None, []
        try:
            return score_signals(task, trajectory, steps=steps, length=length, exclude_episode=exclude), []
        except DataError as error:
            where = trajectory.source or Path(trajectory.key)
            return None, [Skipped(where, f"signals not scored (cameras alone): {error}", SIGNALS_VIEW)]

    def threshold_at(
        self, rule: ScoringRule, t: int, view: str | None = None, *, task: str | None = None
    ) -> float:
        """`rule`'s threshold on `view`'s raw score at frame `t` of a run of `task`: θ, or μ_t + θ·σ_t with a
        band (its task's and view's)."""
        band = self.bands.get(rule.name)
        threshold = self.threshold_of(rule)
        return threshold if band is None else band.for_task(task).line_at(threshold, t, view)
