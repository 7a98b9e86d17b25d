"""What the detector produces over a whole trajectory: a trace (S⁻, S⁺, C, N per view, t_det); the result of
one live step is `robofailring.detection.session.StepResult`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robofailring.data.model import Skipped
from robofailring.detection.band import Band
from robofailring.detection.config import DEFAULT_STRIDE
from robofailring.detection.rules import PAPER, RULES, RuleThresholds, ScoringRule, shown_rules
from robofailring.detection.signal_scores import SignalScores
from robofailring.detection.view_scores import ViewScores
from robofailring.memory.failure import FailureMemory, Neighbor
from robofailring.memory.signals.modality import BOTH, SIGNALS_VIEW, judged_views
from robofailring.memory.success import SuccessMatch


@dataclass
class DetectionTrace(RuleThresholds):
    """A whole replayed trajectory: S_t per view per frame, neighbours, t_det and L."""

    task: str
    episode: str
    length: int
    rule: ScoringRule
    thresholds: dict[str, float]  # per rule name (δ, γ, …): the trace is judged by `rule` at its own
    k: int
    encoder: str
    views: list[str]
    similarity: dict[str, np.ndarray]
    neighbor_ids: dict[str, np.ndarray]
    neighbor_similarity: dict[str, np.ndarray]
    # one row per scored frame; {} after run(keep_queries=False)
    queries: dict[str, np.ndarray] = field(repr=False)
    memory: FailureMemory = field(repr=False)
    skipped_views: list[str] = field(default_factory=list)
    view_frames: dict[str, int] = field(default_factory=dict)  # frames each view had (L bounds them)
    stride: int = DEFAULT_STRIDE  # every `stride`-th frame from frame 0 is scored; the others hold NaN / -1
    skipped_inputs: list[Skipped] = field(default_factory=list)  # files of the episode not read

    @property
    def scored_frames(self) -> np.ndarray:
        """Indices (original frame numbers) of the frames that were scored: 0, stride, 2·stride, …"""
        return np.arange(0, self.length, self.stride)

    success_similarity: dict[str, np.ndarray] = field(default_factory=dict)  # S⁺_t per view
    success_ids: dict[str, np.ndarray] = field(default_factory=dict)  # its success-memory row, -1: none
    in_memory: bool = False  # one of the memory's own episodes, not left out: it meets itself
    placed: dict[str, np.ndarray] = field(
        default_factory=dict, repr=False
    )  # run(place=…) rows per scored frame
    # per rule name: the time-indexed band its calibrated threshold applies to (robofailring.detection.band)
    bands: dict[str, Band] = field(default_factory=dict, repr=False)
    source: Path | None = None  # the trajectory's folder or file, naming what was skipped
    # the robot's own signals scored against the memory's signal memory, fused as the view `signals`
    signals: SignalScores | None = field(default=None, repr=False)
    modality: str = BOTH  # what the fusion judges: `both`, the `cameras` alone or the `signals` alone
    cameras_alone: bool = False  # the memory has the task's signals, the run records none (camera-only data)

    @property
    def scored_views(self) -> list[str]:
        """The views the rule's scores are fused over: the cameras (unless `modality` is `signals`), and
        `signals` where they were scored (unless it is `cameras`)."""
        return judged_views(
            [*self.views, *([SIGNALS_VIEW] if self.signals is not None else [])], self.modality
        )

    @property
    def short_views(self) -> list[Skipped]:
        """The views not scored for having fewer than 2 frames, as inputs skipped: every verb lists them
        and ends with status 3, as build-memory does (docs/errors.md, "When things go wrong")."""
        where = self.source if self.source is not None else Path(self.task, self.episode)
        return [
            Skipped(
                where,
                f"view {view}: {self.view_frames.get(view, 0)} frame(s), fewer than 2: not scored",
                view,
            )
            for view in self.skipped_views
        ]

    @property
    def threshold(self) -> float:
        """The rule's threshold (δ for the paper rule, γ for the contrast rule)."""
        return self.threshold_of(self.rule)

    def scores_of(self, rule: ScoringRule) -> dict[str, np.ndarray]:
        """`rule`'s score per view the trace judges by (`scored_views`: its modality's), from S⁻ and S⁺ (S⁺
        NaN throughout when the memory has no success runs), the signals' last."""
        found = self.all_scores_of(rule)
        return {view: found[view] for view in self.scored_views}

    def all_scores_of(self, rule: ScoringRule) -> dict[str, np.ndarray]:
        """`rule`'s score of every camera view and of the signals where scored, whatever the modality."""
        missing = np.full(self.length, np.nan, np.float32)
        return {
            view: rule.score(self.similarity[view], self.success_similarity.get(view, missing))
            for view in self.views
        } | (
            {SIGNALS_VIEW: rule.score(self.signals.similarity, self.signals.success_similarity)}
            if self.signals is not None
            else {}
        )

    def failure_similarity(self, view: str) -> np.ndarray:
        """S⁻_t of a view, the signals' included."""
        if view == SIGNALS_VIEW and self.signals is not None:
            return self.signals.similarity
        return self.similarity[view]

    def judged_scores_of(self, rule: ScoringRule) -> dict[str, np.ndarray]:
        """What `rule`'s threshold judges, per view: its score, corrected by its band when it has one."""
        scores = self.scores_of(rule)
        band = self.bands.get(rule.name)
        return (
            scores if band is None else {view: band.correct(values, view) for view, values in scores.items()}
        )

    def threshold_line(self, rule: ScoringRule | None = None, view: str | None = None) -> np.ndarray:
        """The threshold of `rule` (default: the trace's) on `view`'s raw score, per frame: constant without
        a band, μ_t + θ·σ_t with one (what a recording draws; with a band per view, `view`'s own, and
        without `view` the band of the max over views)."""
        rule = rule or self.rule
        threshold = self.threshold_of(rule)
        band = self.bands.get(rule.name)
        if band is None:
            return np.full(self.length, threshold, dtype=np.float32)
        return band.line(threshold, self.length, view)

    @property
    def band(self) -> Band | None:
        """The band of the trace's rule, None when its threshold is one number."""
        return self.bands.get(self.rule.name)

    @property
    def shown_rules(self) -> list[ScoringRule]:
        """The rules a recording or report of this trace shows (`robofailring.detection.rules.shown_rules`)."""
        return shown_rules(self.rule, successes=bool(self.success_similarity), failures=self.has_failures)

    @property
    def has_failures(self) -> bool:
        """Whether the memory holds failure entries of this trace's task (neighbours to show)."""
        return self.memory.has_failures(self.task)

    @property
    def scores(self) -> dict[str, np.ndarray]:
        """The score the rule thresholds, per view: S⁻_t (paper), C_t (contrast) or N_t (novelty)."""
        return self.scores_of(self.rule)

    @property
    def view_scores(self) -> ViewScores:
        """The rule's judged per-view scores (band-corrected when it has a band), fused over this trace's
        views (`robofailring.detection.view_scores`)."""
        return self._over_views(self.judged_scores_of(self.rule))

    def _over_views(self, scores: Mapping[str, np.ndarray]) -> ViewScores:
        """`scores` of this trace's scored views (in its view order, the signals last), for fusing."""
        return ViewScores({view: scores[view] for view in self.scored_views}, self.length)

    def nearest_success(self, view: str, t: int) -> SuccessMatch | None:
        """The success frame nearest to the query of `view` at `t`, if the memory has one."""
        successes = self.memory.successes
        if successes is None or view not in self.success_ids:
            return None
        return successes.match(float(self.success_similarity[view][t]), int(self.success_ids[view][t]))

    @property
    def truncated_views(self) -> dict[str, int]:
        """Views longer than L (the shortest used view) and how many of their frames were not scored."""
        return {view: count - self.length for view, count in self.view_frames.items() if count > self.length}

    @property
    def state(self) -> np.ndarray:
        """State_t (eq. 7) fused over views: 1 where any view's score reaches the rule's threshold."""
        return self.view_scores.state(self.threshold)

    @property
    def t_det(self) -> int | None:
        """The first frame at which the detector fires, or None."""
        return self.view_scores.first_at_or_above(self.threshold)

    @property
    def detected(self) -> bool:
        return self.t_det is not None

    @property
    def detected_view(self) -> str | None:
        """The view with the highest score among those over the threshold at t_det."""
        return self.view_scores.detected_view(self.threshold)

    def max_similarity(self) -> np.ndarray:
        """max over views (the signals' included) of S⁻_t (the paper's S_t), per frame."""
        return self._over_views(
            {view: self.failure_similarity(view) for view in self.scored_views}
        ).fused_max()

    def max_score(self) -> np.ndarray:
        """max over views of the rule's judged score, per frame (NaN counts as −∞)."""
        return self.view_scores.fused_max()

    def raw_max_score(self, rule: ScoringRule) -> np.ndarray:
        """max over views of `rule`'s uncorrected score, per frame (NaN where no view was scored)."""
        fused = self._over_views(self.scores_of(rule)).fused_max()
        return np.where(np.isfinite(fused), fused, np.nan)

    def verdict(self) -> str:
        """One line: where the rule fired (frame, view, score against its line), or that it did not and how
        near it came (the judged score's peak, which a band compares with the threshold itself)."""
        rule = self.rule
        if self.t_det is None or self.detected_view is None:
            peak = self.max_score()  # NaN (a frame not scored) is −∞ here
            if not np.isfinite(peak).any():
                return f"no alarm ({rule.name} rule: no frame scored)"
            t = int(np.argmax(peak))
            return (
                f"no alarm ({rule.name} rule: peak {rule.score_name} = {float(peak[t]):.3f} at frame {t} "
                f"< {self.threshold:.3f}{', band-corrected' if self.band is not None else ''})"
            )
        view, t = self.detected_view, self.t_det
        return (
            f"FAILURE detected at frame {t}/{self.length} in view {view} ({rule.name} rule: {rule.score_name} = "
            f"{float(self.scores[view][t]):.3f} ≥ {float(self.threshold_line(view=view)[t]):.3f})"
        )

    def camera_at(self, view: str | None, t: int) -> str | None:
        """`view` when it is a camera; for the signals (or None), the camera view scoring highest at `t`."""
        if view in self.views:
            return view
        scores = self.all_scores_of(self.rule)
        scored = [(float(scores[v][t]), v) for v in self.views if np.isfinite(scores[v][t])]
        return max(scored)[1] if scored else None

    def neighbors(self, view: str, t: int) -> list[Neighbor]:
        """The failure entries nearest to `view`'s query at `t` (none for the signals: `signals.nearest_failure`)."""
        if view not in self.neighbor_ids:
            return []
        return self.memory.neighbors(self.neighbor_similarity[view][t], self.neighbor_ids[view][t])

    def with_delta(self, delta: float) -> DetectionTrace:
        """The same trace with another δ (S_t does not depend on δ); its rule stays."""
        return DetectionTrace(**{**self.__dict__, "thresholds": {**self.thresholds, PAPER.name: delta}})

    def with_rule(self, rule: ScoringRule, threshold: float) -> DetectionTrace:
        """The same trace judged by another rule at its threshold (the scores do not change)."""
        thresholds = {**self.thresholds, rule.name: threshold}
        return DetectionTrace(**{**self.__dict__, "rule": rule, "thresholds": thresholds})

    def to_dict(self) -> dict[str, Any]:
        """The JSON shape of `robofailring detect --json`."""
        views: dict[str, Any] = {}
        by_rule = {rule.name: self.all_scores_of(rule) for rule in RULES.values()}
        for view in self.views:
            top: list[dict[str, Any] | None] = []
            for t in range(self.length):
                found = self.neighbors(view, t)
                if not found:
                    top.append(None)
                    continue
                entry = found[0].entry
                moment = {"frame": entry.frame, "length": entry.length} if entry.frame is not None else {}
                top.append(
                    {
                        "task": entry.task,
                        "symbol": entry.symbol,
                        "view": entry.view,
                        "episode": entry.episode,
                        "similarity": round(found[0].similarity, 6),
                        **moment,  # a dense memory's entry: the moment of its run that matched
                    }
                )
            views[view] = {
                "similarity": _rounded(self.similarity[view]),
                "top_neighbor": top,
                "failure_similarity": _rounded(self.similarity[view]),
                "success_similarity": _rounded(
                    self.success_similarity.get(view, np.full(self.length, np.nan))
                ),
                **{name: _rounded(scores[view]) for name, scores in by_rule.items()},  # every rule's score
            }
        return {
            "task": self.task,
            "episode": self.episode,
            "length": self.length,
            "delta": self.delta,
            "score": self.rule.name,
            "threshold": self.threshold,
            "thresholds": {rule.name: self.threshold_of(rule) for rule in RULES.values()},  # by rule name
            "failure_entries": self.memory.task_size(self.task),
            "k": self.k,
            "encoder": self.encoder,
            "band": self.band.kind if self.band is not None else None,
            "threshold_line": _rounded(self.threshold_line()) if self.band is not None else None,
            "t_det": self.t_det,
            "detected_view": self.detected_view,
            "skipped_views": self.skipped_views,
            "unscored_frames": self.truncated_views,
            "stride": self.stride,
            "skipped_inputs": [skipped.to_dict() for skipped in self.skipped_inputs],
            "in_memory": self.in_memory,
            "views": views,
            "modality": self.modality,
            "signals": self._signals_dict(by_rule),
        }

    def _signals_dict(self, by_rule: Mapping[str, Mapping[str, np.ndarray]]) -> dict[str, Any] | None:
        """The robot's signals in `to_dict`: S⁻, S⁺ and every rule's score per frame, the nearest failure
        and normal runs at t_det and what deviated most there (None: not scored)."""
        signals = self.signals
        if signals is None:
            return None
        at = self.t_det
        return {
            "failure_similarity": _rounded(signals.similarity),
            "success_similarity": _rounded(signals.success_similarity),
            **{name: _rounded(scores[SIGNALS_VIEW]) for name, scores in by_rule.items()},
            "at_t_det": None
            if at is None
            else {
                "nearest_failure": signals.nearest_failure(at),
                "nearest_success": signals.nearest_success(at),
                "deviations": [{"dimension": d, "sigma": round(v, 3)} for d, v in signals.deviations(at)],
            },
        }


def self_match_warning(keys: Sequence[str], *, shown: int = 5) -> str:
    """The one warning line for trajectories scored against a memory that holds them (`in_memory`)."""
    named = ", ".join(keys[:shown]) + (f" and {len(keys) - shown} more" if len(keys) > shown else "")
    which = (
        f"trajectory {named} is one of the memory's own episodes"
        if len(keys) == 1
        else f"{len(keys)} trajectories are the memory's own episodes ({named})"
    )
    return (
        f"warning: {which}, so its scores include a self-match (S⁻ = 1 is no detection); "
        "pass --leave-one-out to hide each trajectory's own episode"
    )


def _rounded(values: np.ndarray) -> list[float | None]:
    return [None if np.isnan(v) else round(float(v), 6) for v in values]
