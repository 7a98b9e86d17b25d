"""One task's signal memory (`TaskSignals`): its layout, derived features, normalisation, and the failure and
success entries in exact Faiss indexes; the paired vectors of a run's features and the nearest entries of a
query (the vectors and similarity: `robofailring.memory.signals.memory`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Final

import numpy as np

from robofailring.data.signals import FLOAT32_MAX
from robofailring.errors import DataError
from robofailring.memory.index import FLAT, IndexSpec, TaskIndex
from robofailring.memory.signals.derived import Derivation
from robofailring.memory.signals.layout import ACTION_LAGS, SignalLayout
from robofailring.memory.signals.rows import Rows, search_entries
from robofailring.memory.signals.select import Selection

START_WEIGHT: Final[float] = 0.5  # the start state's weight in a memory from before it was a setting
# the largest start weight: the start state, a few σ once normalised, then outweighs every other element a
# hundredfold; a larger one only overflows the float32 vectors (1e308 would make them infinite)
MAX_START_WEIGHT: Final[float] = 100.0


class TaskSignals:
    """One task's signal memory: its layout, derived features, normalisation and the failure and success
    entries' indexes."""

    def __init__(
        self,
        layout: SignalLayout,
        mean: np.ndarray,
        scale: np.ndarray,
        vectors: Mapping[str, np.ndarray],
        rows: Mapping[str, Rows],
        derivation: Derivation | None = None,
        start_weight: float = START_WEIGHT,
        selection: Selection | None = None,
        chose: str = "",
    ) -> None:
        self.layout, self.mean, self.scale = layout, np.asarray(mean), np.asarray(scale)
        self.selection = selection  # the elements its vectors keep (`--signals auto`: chosen from its runs)
        self.chose = chose  # why none were chosen, where choosing was asked for
        self.derivation = derivation
        self.start_weight = float(start_weight)
        self.vectors = {kind: np.asarray(v, np.float32) for kind, v in vectors.items()}
        self.rows = dict(rows)
        self.indexes = {
            kind: TaskIndex.build(
                search_entries(v), np.arange(len(v)), list(self.rows[kind].episodes), IndexSpec(FLAT)
            )
            for kind, v in self.vectors.items()
            if len(v)
        }

    @property
    def widths(self) -> tuple[int, int]:
        """(state, action) widths of its features: the layout's, with the derived columns in the state."""
        state, action = self.layout.widths
        return state + (self.derivation.width if self.derivation is not None else 0), action

    @property
    def width(self) -> int:
        """Its vectors' length."""
        full = vector_width(*self.widths)
        return full if self.selection is None else len(self.selection.columns)

    def derived(self, features: np.ndarray) -> np.ndarray:
        """One run's features with the derived columns after the state: [state ‖ derived ‖ action ‖ t]."""
        features = np.asarray(features, np.float64)
        if self.derivation is None:
            return features
        state = self.layout.widths[0]
        return np.concatenate([features[:, :state], self.derivation.added(features), features[:, state:]], 1)

    def vectors_of(self, features: np.ndarray, frames: np.ndarray | None = None) -> np.ndarray:
        """The paired vectors (module docstring) of one run's raw features, one per frame (of `frames` only,
        when given, reading only the rows it needs: frames up to it where features are derived). DataError:
        a vector beyond float32's range (a value far outside the success runs' spread)."""
        features = np.asarray(features, np.float64)
        at = np.arange(len(features)) if frames is None else np.asarray(frames, np.int64)
        if self.derivation is not None:
            features = self.derived(features[: int(at.max(initial=0)) + 1])
        lagged = [features[np.maximum(at - lag, 0)] for lag in ACTION_LAGS]
        return self.paired(features[0], features[at], lagged)

    def paired(self, first: np.ndarray, now: np.ndarray, lagged: Sequence[np.ndarray]) -> np.ndarray:
        """The paired vectors of the rows `now` (N, W) of features with their derived columns, from the run's
        first such row and the rows `ACTION_LAGS` frames before each of `now` (frame 0 before the start):
        what `vectors_of` gives, for a live step that keeps only those rows."""
        state_width, action_width = self.widths

        def z(rows: np.ndarray) -> np.ndarray:
            return (np.asarray(rows, np.float64) - self.mean) / self.scale

        start_z, now_z = z(first), z(now)
        actions = [z(rows)[:, state_width : state_width + action_width] for rows in lagged]
        start = np.broadcast_to(self.start_weight * start_z[:state_width], (len(now_z), state_width))
        change = now_z[:, :state_width] - start_z[:state_width]
        vectors = np.concatenate([start, change, *actions, now_z[:, -1:]], axis=1)
        beyond = ~(np.abs(vectors) <= FLOAT32_MAX)
        if beyond.any():
            row, column = (int(i) for i in np.argwhere(beyond)[0])
            raise DataError(
                f"its signals are too far from the task's success runs to be kept: element {column} of frame "
                f"{row}'s vector is {vectors[row, column]:.3g} once normalised, beyond float32's range"
            )
        paired = vectors.astype(np.float32)
        return paired if self.selection is None else self.selection.apply(paired)

    def search(
        self, vectors: np.ndarray, kind: str, *, exclude_episode: str | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(similarity, entry row) of the nearest `failure` or `success` entry per vector; NaN and −1 where
        the task has none (or only the excluded episode's)."""
        vectors = np.ascontiguousarray(vectors, np.float32)
        index = self.indexes.get(kind)
        if index is None:
            return np.full(len(vectors), np.nan, np.float32), np.full(len(vectors), -1, np.int64)
        queries = np.concatenate([vectors, np.ones((len(vectors), 1), np.float32)], axis=1)
        products, ids = index.search(queries, 1, exclude_episode=exclude_episode)
        squared = np.maximum(np.einsum("ij,ij->i", vectors, vectors) - 2 * products[:, 0], 0.0)
        similarity = np.exp(-squared / vectors.shape[1]).astype(np.float32)
        return np.where(ids[:, 0] >= 0, similarity, np.nan).astype(np.float32), ids[:, 0]

    def deviations(self, vector: np.ndarray, row: int, *, top: int = 3) -> list[tuple[str, float]]:
        """The elements of `vector` furthest from success entry `row`, in the success runs' spreads (σ)."""
        difference = np.asarray(vector, np.float64) - self.vectors["success"][row]
        order = np.argsort(-np.abs(difference))[:top]
        derived = self.derivation.names(self.layout.raw_columns()) if self.derivation is not None else []
        columns = self.layout.columns(derived)
        columns = columns if self.selection is None else self.selection.names(columns)
        return [(columns[i], float(difference[i])) for i in order]


def vector_width(state: int, action: int) -> int:
    """A paired vector's width from the (state, action) widths: [start ‖ change ‖ lagged actions ‖ t]."""
    return 2 * state + len(ACTION_LAGS) * action + 1


def check_start_weight(weight: object) -> float:
    """A start weight (`--signal-start-weight`) as a float; ValueError unless a number from 0 to `MAX_START_WEIGHT`."""
    if (
        isinstance(weight, bool)
        or not isinstance(weight, (int, float))
        or not 0 <= weight <= MAX_START_WEIGHT  # NaN too
    ):
        raise ValueError(
            f"a signal start weight (--signal-start-weight) must be a number from 0 to {MAX_START_WEIGHT:g} "
            f"(0 leaves the start state out, 0.5 weighs it as memories from before the setting do), got {weight!r}"
        )
    return float(weight)
