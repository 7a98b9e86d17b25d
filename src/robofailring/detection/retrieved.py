"""What one batched search of both memories answers for T frames of each view (`FailureDetector.retrieve`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Retrieved:
    """The batched core's answer for T frames of each view: queries, the K nearest failure ends, S⁺."""

    queries: dict[str, np.ndarray]  # (T, 2d) per view: (f(I_0) ‖ f(I_t))
    neighbor_similarity: dict[str, np.ndarray]  # (T, K) per view; column 0 is S⁻_t
    neighbor_ids: dict[str, np.ndarray]  # (T, K) global memory ids, -1: none
    success_similarity: dict[str, np.ndarray]  # (T,) S⁺_t per view; empty without success runs
    success_ids: dict[str, np.ndarray]  # (T,) its success-memory row, -1: none

    def similarity(self, view: str) -> np.ndarray:
        """S⁻_t of `view`: the nearest failure end's similarity per frame."""
        return self.neighbor_similarity[view][:, 0].copy()

    def without_blank(self, blank: dict[str, np.ndarray]) -> Retrieved:
        """This answer with the frames of `blank` ((T,) bool per view) matching nothing: NaN similarities
        and id -1, so a frame the encoder sees as nothing (a zero embedding, e.g. an all-black image)
        never reaches a threshold (a zero query's cosine of 0 would reach γ = 0)."""
        if not any(mask.any() for mask in blank.values()):
            return self

        def masked(field: dict[str, np.ndarray], empty: float) -> dict[str, np.ndarray]:
            out = {}
            for view, values in field.items():
                values = values.copy()
                values[blank[view]] = empty
                out[view] = values
            return out

        return replace(
            self,
            neighbor_similarity=masked(self.neighbor_similarity, np.nan),
            neighbor_ids=masked(self.neighbor_ids, -1),
            success_similarity=masked(self.success_similarity, np.nan),
            success_ids=masked(self.success_ids, -1),
        )

    def without_queries(self) -> Retrieved:
        """The same answer without its (T, 2d) queries, the one part as large as the frames' embeddings."""
        return replace(self, queries={})

    @staticmethod
    def joined(parts: Sequence[Retrieved]) -> Retrieved:
        """Consecutive chunks of frames of the same views, as one answer."""

        def join(field: str) -> dict[str, np.ndarray]:
            views = getattr(parts[0], field)
            return {view: np.concatenate([getattr(part, field)[view] for part in parts]) for view in views}

        return Retrieved(
            queries=join("queries"),
            neighbor_similarity=join("neighbor_similarity"),
            neighbor_ids=join("neighbor_ids"),
            success_similarity=join("success_similarity"),
            success_ids=join("success_ids"),
        )
