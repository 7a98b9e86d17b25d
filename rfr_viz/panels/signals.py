"""The signals panel: the robot's own signals (joint state, gripper, actions) on the same two timelines
as the cameras and scores, one plot per signal with a named series per dimension (`/signals/<name>`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from rfr_viz.panels.scores import ROW_BATCH, time_columns
from rfr_viz.paths import signal
from rfr_viz.styles import VIEW_COLOURS
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.signals import SignalValues
from robofailring.extras import needs_extra

with needs_extra("viz"):
    import rerun as rr


def recorded_signals(trajectory: Trajectory, length: int) -> tuple[dict[str, SignalValues], list[Skipped]]:
    """The trajectory's signals that can be read, cut to the recording's `length`, and those that cannot."""
    found, skipped = trajectory.read_signals()
    return {name: _cut(values, length) for name, values in found.items()}, skipped


def _cut(values: SignalValues, length: int) -> SignalValues:
    return SignalValues(values.name, values.kind, values.dims, values.values[:length])


def log_signals(
    rec: rr.RecordingStream,
    signals: Mapping[str, SignalValues],
    *,
    fps: float,
    at: Callable[[str], str] = signal,
) -> None:
    """Each signal at `at(name)` (`/signals/<name>`): a static style naming every dimension, then its rows
    as columns."""
    for name, values in signals.items():
        path = at(name)
        width = values.values.shape[1]
        rec.log(
            path,
            rr.SeriesLines(
                names=list(values.dims), colors=[VIEW_COLOURS[i % len(VIEW_COLOURS)] for i in range(width)]
            ),
            static=True,
        )
        frames = np.arange(len(values.values))
        for start in range(0, len(frames), ROW_BATCH):
            batch = frames[start : start + ROW_BATCH]
            rec.send_columns(
                path,
                indexes=time_columns(batch, fps),
                columns=rr.Scalars.columns(scalars=values.values[batch].ravel()).partition(
                    [width] * len(batch)
                ),
            )
