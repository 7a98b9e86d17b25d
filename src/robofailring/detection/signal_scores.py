"""The signal modality's scores over a trajectory or a live session: S⁻ and S⁺ of the robot's own signals
against the task's signal memory (`robofailring.memory.signals.memory`), fused with the camera views as the
view named `signals`, and what deviated most from the nearest normal frame."""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from robofailring.data.model import Trajectory
from robofailring.data.signals import FLOAT32_MAX
from robofailring.errors import DataError
from robofailring.memory.signals.derived import RunningDerivation
from robofailring.memory.signals.layout import ACTION_LAGS, read_features
from robofailring.memory.signals.task import TaskSignals

__all__ = ["SignalHistory", "SignalScores", "cameras_alone_note", "score_signals"]


@dataclass(frozen=True)
class SignalScores:
    """One run's signal scores per frame (NaN, −1: not scored) and the vectors they were found with."""

    similarity: np.ndarray  # S⁻_t: the nearest failure entry's similarity
    success_similarity: np.ndarray  # S⁺_t: the nearest success entry's
    failure_rows: np.ndarray  # that failure entry's row in the task's signal memory, −1: none
    success_rows: np.ndarray  # that success entry's row, −1: none
    vectors: np.ndarray = field(repr=False)  # (L, n) the paired vectors (zeros where not scored)
    task: TaskSignals = field(repr=False)

    def nearest_failure(self, t: int) -> tuple[str, str, int] | None:
        """(episode, symbol, frame) of the failure entry nearest at frame `t`, if any."""
        row = int(self.failure_rows[t])
        if row < 0:
            return None
        rows = self.task.rows["failure"]
        return str(rows.episodes[row]), str(rows.symbols[row]), int(rows.frames[row])

    def nearest_success(self, t: int) -> tuple[str, int] | None:
        """(episode, frame) of the success entry nearest at frame `t`, if any."""
        row = int(self.success_rows[t])
        if row < 0:
            return None
        rows = self.task.rows["success"]
        return str(rows.episodes[row]), int(rows.frames[row])

    def deviations(self, t: int, *, top: int = 3) -> list[tuple[str, float]]:
        """The signal dimensions furthest from the nearest normal frame at `t`, in σ of the success runs."""
        row = int(self.success_rows[t])
        return [] if row < 0 else self.task.deviations(self.vectors[t], row, top=top)

    def deviation_text(self, t: int) -> str:
        """`gripper_width/width (change since the start) +4.2σ, …` at frame `t`, or '' without a success."""
        return ", ".join(f"{name} {value:+.1f}σ" for name, value in self.deviations(t))


def cameras_alone_note(keys: Sequence[str], *, shown: int = 5) -> str:
    """The one note for runs that record no robot signals at all, scored against a memory that has their
    task's: their cameras judge alone. Not an input skipped (a camera-only dataset lacks nothing it has)."""
    named = ", ".join(keys[:shown]) + (f" and {len(keys) - shown} more" if len(keys) > shown else "")
    if len(keys) == 1:
        return f"note: trajectory {named} records no robot signals; the memory has its task's, so its cameras judge alone"
    return (
        f"note: {len(keys)} trajectories ({named}) record no robot signals; the memory has their tasks', so "
        "their cameras judge alone"
    )


def score_signals(
    task: TaskSignals, trajectory: Trajectory, *, steps: np.ndarray, length: int, exclude_episode: str | None
) -> SignalScores:
    """The signal scores of `trajectory` at its scored frames `steps` (DataError: its signals cannot be read)."""
    features = read_features(trajectory, task.layout)[:length]
    if len(features) < length:
        raise DataError(f"{trajectory.key}: its signals have {len(features)} rows for {length} frames")
    vectors = task.vectors_of(features)
    failure, failure_rows = task.search(vectors[steps], "failure", exclude_episode=exclude_episode)
    success, success_rows = task.search(vectors[steps], "success", exclude_episode=exclude_episode)

    def on_frames(values: np.ndarray, fill: float) -> np.ndarray:
        full = np.full(length, fill, dtype=values.dtype)
        full[steps] = values
        return full

    return SignalScores(
        similarity=on_frames(failure, np.nan),
        success_similarity=on_frames(success, np.nan),
        failure_rows=on_frames(failure_rows, -1),
        success_rows=on_frames(success_rows, -1),
        vectors=vectors,
        task=task,
    )


class SignalHistory:
    """A live session's signals so far, kept in constant space: the first step's features (the start state),
    the last few (the action window, `ACTION_LAGS`) and the derived features' running state, so a step costs
    the same at step 40,000 as at step 10 (`robofailring.memory.signals.memory`)."""

    def __init__(self, task: TaskSignals) -> None:
        self.task = task
        self.steps = 0
        self._running = RunningDerivation(task.derivation) if task.derivation is not None else None
        self._first: np.ndarray | None = None  # the first step's features, derived columns included
        self._recent: deque[np.ndarray] = deque(maxlen=max(ACTION_LAGS) + 1)  # the last steps' features

    def step(
        self, signals: Mapping[str, np.ndarray], *, exclude_episode: str | None
    ) -> tuple[float, float, np.ndarray, int, int]:
        """Add this step's signals ({name: (D,) values}); (S⁻, S⁺, its vector, failure row, success row)."""
        layout = self.task.layout
        missing = [name for name in layout.names if name not in signals]
        if missing:
            raise DataError(
                f"step {self.steps}: signals= lacks {missing[0]!r}; the task's signal memory uses "
                f"{', '.join(layout.names)}"
            )
        values = {}
        for name, dims in (*layout.state, *layout.action):
            row = np.asarray(signals[name], dtype=np.float64).reshape(-1)
            own = layout.full.get(name, dims)  # the whole signal, when the memory uses some of it
            if len(row) != len(own) or not (np.abs(row) <= FLOAT32_MAX).all():
                raise DataError(
                    f"step {self.steps}: signal {name!r} must be {len(own)} finite numbers within float32's "
                    f"range ({', '.join(own)}), got {row.tolist()}"
                )
            values[name] = layout.select(name, own, row[None], f"step {self.steps}")
        features = layout.features(values, 1)[0]
        features[-1] = self.steps  # the frame number
        running = self._running
        if running is not None:  # [state ‖ derived ‖ action ‖ t], as `TaskSignals.derived` lays a run out
            state = layout.widths[0]
            added, running = running.add(features)
            features = np.concatenate([features[:state], added, features[state:]])
        first = features if self._first is None else self._first
        recent = [*self._recent, features]
        lagged = [recent[max(len(recent) - 1 - lag, 0)][None] for lag in ACTION_LAGS]
        try:
            vector = self.task.paired(first, features[None], lagged)
        except DataError as error:
            raise DataError(f"step {self.steps}: {error}") from error
        self._first, self._running = first, running  # kept only once the step is whole
        self._recent.append(features)
        self.steps += 1
        failure, failure_row = self.task.search(vector, "failure", exclude_episode=exclude_episode)
        success, success_row = self.task.search(vector, "success", exclude_episode=exclude_episode)
        return float(failure[0]), float(success[0]), vector[0], int(failure_row[0]), int(success_row[0])

    def scores(self, signals: Mapping[str, np.ndarray], *, exclude_episode: str | None) -> SignalScores:
        """`step`, as the one-row `SignalScores` of this step (its nearest runs and deviations at row 0)."""
        failure, success, vector, failure_row, success_row = self.step(
            signals, exclude_episode=exclude_episode
        )
        return SignalScores(
            similarity=np.full(1, failure, np.float32),
            success_similarity=np.full(1, success, np.float32),
            failure_rows=np.full(1, failure_row, np.int64),
            success_rows=np.full(1, success_row, np.int64),
            vectors=vector[None],
            task=self.task,
        )
