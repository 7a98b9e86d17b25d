"""The live step API: a `DetectorSession` per episode, fed each step's frames (and the robot's signals), the
`StepResult` of each step, and the `StepSink` that sees every step (`rfr_viz.LiveRecording` streams it to a Rerun viewer)."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from robofailring.data.model import Frame
from robofailring.detection.rules import RULES, ScoringRule
from robofailring.detection.signal_scores import SignalHistory, SignalScores
from robofailring.detection.view_scores import ViewScores
from robofailring.encoders.base import unusable
from robofailring.errors import BlindCameraWarning
from robofailring.memory.entry import Neighbor
from robofailring.memory.signals.modality import SIGNALS_VIEW, judged_views
from robofailring.memory.success import SuccessMatch

if TYPE_CHECKING:
    from robofailring.detection.retrieved import Retrieved
    from robofailring.memory.failure import FailureMemory


@dataclass(frozen=True)
class StepResult:
    """What the detector says about one time step."""

    t: int
    similarity: dict[str, float]  # S⁻_t per view (the paper's S_t)
    neighbors: dict[str, list[Neighbor]]
    alarm: bool  # State_t: some view's score reaches the threshold
    fired_views: list[str]  # the views whose score reaches it, in view order
    score: dict[str, float]  # the rule's score per view (S_t, C_t or N_t; NaN: not scored)
    rule: ScoringRule
    threshold: float  # what `score` is judged against at this step: θ, or μ_t + θ·σ_t with a band
    detected_view: str | None  # the firing view with the highest score, None without an alarm
    success_similarity: dict[str, float] = field(default_factory=dict)  # S⁺_t per view (NaN: none)
    nearest_success: dict[str, SuccessMatch | None] = field(default_factory=dict)  # its success frame
    # every registered rule's score per view, by rule name (paper: S⁻_t, contrast: C_t, novelty: N_t, …)
    rule_scores: dict[str, dict[str, float]] = field(default_factory=dict)
    # every registered rule's threshold on its raw score at this step, by rule name (θ, or μ_t + θ·σ_t)
    thresholds: dict[str, float] = field(default_factory=dict)
    queries: dict[str, np.ndarray] = field(default_factory=dict, repr=False)  # (f(I_0) ‖ f(I_t)) per view
    # every registered rule's threshold on each judged view's raw score at this step, by rule name and view: the
    # view's own band's line where it has one (fusion per-view, per-modality), else `thresholds[<rule>]`
    view_thresholds: dict[str, dict[str, float]] = field(default_factory=dict)
    # camera views that saw nothing at this step (a black, single-colour or NaN frame now, or as I_0): not
    # scored, so `alarm` is False for them whatever the robot does (a BlindCameraWarning says it once)
    blind_views: list[str] = field(default_factory=list)

    @property
    def usable(self) -> bool:
        """Whether some view was judged at this step: False when every camera was blind and no signal was
        scored, and then `alarm=False` means nothing (a camera died, not a run gone well)."""
        return any(value == value for value in self.score.values())

    @property
    def state(self) -> bool:
        """`alarm`, by its name in the paper (State_t, eq. 7)."""
        return self.alarm

    @property
    def camera_view(self) -> str | None:
        """The camera view whose neighbours explain the alarm: the firing view, or, when the robot's signals
        fired, the camera scoring highest (None without an alarm)."""
        if self.detected_view is None or self.detected_view in self.neighbors:
            return self.detected_view
        cameras = [
            (score, view) for view, score in self.score.items() if view in self.neighbors and score == score
        ]
        return max(cameras)[1] if cameras else None


class SessionDetector(Protocol):
    """What a session asks of its detector (`robofailring.detection.detector.FailureDetector`)."""

    memory: FailureMemory
    modality: str

    def encode(self, frames: Sequence[np.ndarray | Frame], views: Sequence[str]) -> np.ndarray: ...

    def retrieve(
        self,
        task: str,
        first: Mapping[str, np.ndarray],
        current: Mapping[str, np.ndarray],
        *,
        exclude_episode: str | None = None,
    ) -> Retrieved: ...

    def threshold_at(
        self, rule: ScoringRule, t: int, view: str | None = None, *, task: str | None = None
    ) -> float: ...


class StepSink(Protocol):
    """Receives every step of a live session, e.g. `rfr_viz.LiveRecording` streams it to a Rerun viewer."""

    def on_step(
        self, session: DetectorSession, frames: Mapping[str, np.ndarray | Frame], result: StepResult
    ) -> None: ...


class DetectorSession:
    """Per-episode state of the step API: the first frame of every view and the step counter."""

    def __init__(
        self,
        detector: SessionDetector,
        task: str,
        rule: ScoringRule,
        *,
        exclude_episode: str | None,
        sink: StepSink | None = None,
    ) -> None:
        self.detector = detector
        self.task = task
        self.rule = rule  # the task's rule (`FailureDetector.rule_for`)
        self.exclude_episode = exclude_episode
        self.sink = sink
        self._first: dict[str, np.ndarray] = {}
        memory_signals = detector.memory.signals
        task_signals = memory_signals.task(task) if memory_signals is not None else None
        self._signals = SignalHistory(task_signals) if task_signals is not None else None
        self.t = 0
        self.fired_at: int | None = None
        self.blind_steps: dict[str, list[int]] = {}  # per camera view, the steps it saw nothing at
        # the robot's signals at the last step, scored (one row: S⁻, S⁺, their nearest runs); None: not given
        self.signal_scores: SignalScores | None = None

    def step(
        self, frames: Mapping[str, np.ndarray | Frame], *, signals: Mapping[str, np.ndarray] | None = None
    ) -> StepResult:
        """Feed the current frame of each view and, where the memory has the task's signals, the robot's
        `signals` now ({name: (D,) values}: joint state, gripper, the action commanded); the first call
        also fixes I_0 per view and the start state. Without `signals` the cameras judge alone."""
        detector = self.detector
        views = list(frames)
        embeddings = detector.encode(list(frames.values()), views)
        current = {view: embedding[None] for view, embedding in zip(views, embeddings, strict=True)}
        first = {view: self._first.setdefault(view, current[view][0]) for view in views}
        blind = [view for view in views if unusable(np.stack([first[view], current[view][0]])).any()]
        self._say_blind(blind)
        found = detector.retrieve(self.task, first, current, exclude_episode=self.exclude_episode)
        missing = np.full(1, np.nan, np.float32)
        failure = {view: found.similarity(view) for view in views}
        success = {view: found.success_similarity.get(view, missing) for view in views}
        self.signal_scores = None
        if self._signals is not None and signals is not None:
            self.signal_scores = self._signals.scores(signals, exclude_episode=self.exclude_episode)
            failure[SIGNALS_VIEW] = self.signal_scores.similarity
            success[SIGNALS_VIEW] = self.signal_scores.success_similarity
        scored = judged_views(failure, detector.modality)  # the cameras, and the signals where given
        rule = self.rule
        threshold = detector.threshold_at(rule, self.t, task=self.task)
        scores = ViewScores({view: rule.score(failure[view], success[view]) for view in scored}, 1)
        successes = detector.memory.successes
        view_thresholds = {  # every rule's line on each view's raw score: that view's band's, where it has one
            name: {view: detector.threshold_at(each, self.t, view, task=self.task) for view in scored}
            for name, each in {**RULES, rule.name: rule}.items()
        }
        lines = view_thresholds[rule.name]
        fired = scores.firing(lines, 0)
        result = StepResult(
            t=self.t,
            similarity={view: float(failure[view][0]) for view in scored},
            neighbors={
                view: detector.memory.neighbors(
                    found.neighbor_similarity[view][0], found.neighbor_ids[view][0]
                )
                for view in views
            },
            alarm=bool(fired),
            fired_views=fired,
            score={view: float(scores.by_view[view][0]) for view in scored},
            rule=rule,
            threshold=threshold,
            detected_view=scores.strongest(lines, 0),
            success_similarity={view: float(success[view][0]) for view in scored},
            nearest_success={
                view: successes.match(
                    float(found.success_similarity[view][0]), int(found.success_ids[view][0])
                )
                for view in views
            }
            if successes is not None
            else {},
            rule_scores={
                name: {view: float(each.score(failure[view], success[view])[0]) for view in scored}
                for name, each in RULES.items()
            },
            thresholds={
                name: detector.threshold_at(each, self.t, task=self.task) for name, each in RULES.items()
            },
            queries={view: found.queries[view][0] for view in views},
            blind_views=blind,
            view_thresholds=view_thresholds,
        )
        if fired and self.fired_at is None:
            self.fired_at = self.t
        if self.sink is not None:
            self.sink.on_step(self, frames, result)
        self.t += 1
        return result

    def _say_blind(self, blind: Sequence[str]) -> None:
        """Keep the steps each view was blind at; warn the first time a view is (never once per step)."""
        for view in blind:
            steps = self.blind_steps.setdefault(view, [])
            if not steps:
                first = "its first frame" if unusable(self._first[view][None])[0] else f"frame {self.t}"
                warnings.warn(
                    f"{self.task} view {view}: {first} is blank to the encoder (black, one colour or not a "
                    "number): the view is not scored while it sees nothing, its alarm=False means nothing "
                    "(StepResult.blind_views names it at each such step; a camera gone dark?)",
                    BlindCameraWarning,
                    stacklevel=3,
                )
            steps.append(self.t)
