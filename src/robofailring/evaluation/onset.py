"""Alarms against a failure's onset (issue 21): the delay after it, and the alarms that come before it.

T_s = 1 − t_det/L says how early an alarm comes in the episode; where the data says where the failure
starts (`Trajectory.onset_frame`), the delay t_det − onset says how long it took to notice, and an alarm
before onset (premature) fired before there was anything to see. Counts say how many failure runs had a
known onset; seconds use the data's fps, given only when every delayed run has one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from robofailring.evaluation.metrics import ScoredTrajectory, json_number, mean_or_nan, median_or_nan


@dataclass(frozen=True)
class OnsetDelay:
    """One rule at one threshold: the failure runs with a known onset, split by when their first alarm came."""

    failures: int  # failure runs tested
    delays: tuple[int, ...]  # t_det − onset (frames) of each run alarmed at or after its onset
    delay_seconds: tuple[float, ...] | None  # the same in seconds; None when a run has no fps
    premature: int  # runs whose first alarm came before their onset
    missed: int  # runs with a known onset and no alarm

    @property
    def known(self) -> int:
        """Failure runs with a known onset: after onset + premature + missed."""
        return len(self.delays) + self.premature + self.missed

    @property
    def mean_frames(self) -> float:
        return mean_or_nan(self.delays)

    @property
    def median_frames(self) -> float:
        return median_or_nan(self.delays)

    @property
    def mean_seconds(self) -> float:
        return mean_or_nan(self.delay_seconds or ())

    @property
    def median_seconds(self) -> float:
        return median_or_nan(self.delay_seconds or ())

    def to_dict(self) -> dict[str, Any]:
        return {
            "failures": self.failures,
            "onset_known": self.known,
            "after_onset": len(self.delays),
            "premature": self.premature,
            "missed": self.missed,
            "delay_frames_mean": json_number(self.mean_frames),
            "delay_frames_median": json_number(self.median_frames),
            "delay_seconds_mean": json_number(self.mean_seconds),
            "delay_seconds_median": json_number(self.median_seconds),
        }

    def markdown_cells(self) -> str:
        """`| known / failures | after | premature | missed | mean, median (frames) | mean, median (s) |`."""
        seconds = (
            f"{_number(self.mean_seconds)}, {_number(self.median_seconds)}"
            if self.delay_seconds is not None
            else "— (no fps)"
        )
        return (
            f"| {self.known} / {self.failures} | {len(self.delays)} | {self.premature} | {self.missed} | "
            f"{_number(self.mean_frames)}, {_number(self.median_frames)} | {seconds} |"
        )


ONSET_HEADER = (
    "| rule | onset known / failures | alarm at or after onset | premature (before onset) | missed | "
    "delay mean, median (frames) | delay mean, median (s) |\n"
    "|---|---:|---:|---:|---:|---:|---:|"
)


def onset_delay(scored: Sequence[ScoredTrajectory], threshold: float) -> OnsetDelay:
    """Where each failure run with a known onset was first alarmed at `threshold`, against that onset."""
    failures = [t for t in scored if t.is_failure]
    delays: list[int] = []
    seconds: list[float] | None = []
    premature = missed = 0
    for trajectory in failures:
        if trajectory.onset_frame is None:
            continue
        t_det = trajectory.t_det(threshold)
        if t_det is None:
            missed += 1
        elif t_det < trajectory.onset_frame:
            premature += 1
        else:
            delays.append(t_det - trajectory.onset_frame)
            fps = trajectory.fps
            if seconds is not None and fps is not None and math.isfinite(fps) and fps > 0:
                seconds.append(delays[-1] / fps)
            else:
                seconds = None
    return OnsetDelay(
        failures=len(failures),
        delays=tuple(delays),
        delay_seconds=tuple(seconds) if seconds is not None else None,
        premature=premature,
        missed=missed,
    )


def _number(value: float) -> str:
    return "—" if math.isnan(value) else f"{value:.2f}"
