"""What the monitor puts in `info["robofailring"]` at every step: the detector's verdict on that step."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Final

from robofailring.detection.session import StepResult

INFO_KEY: Final[str] = "robofailring"  # info["robofailring"]: the step's `Verdict`


@dataclass(frozen=True)
class NearestFailure:
    """The memory's nearest failure at an alarm, with its grounded cause (paper §3.4)."""

    view: str  # the camera whose neighbours explain the alarm
    task: str
    episode: str
    symbol: str
    cause: str  # the grounded sentence: the label's own description, else G(symbol)
    similarity: float


@dataclass(frozen=True)
class Verdict:
    """The detector's verdict on one step of an episode: the (observation, action) pair the step executed.

    `scores` holds the rule's score per camera view and, where the robot's signals were scored, under
    `signals`; the alarm fires when one reaches `threshold` (its band's line at this step, where calibrated
    with one). `skipped` names what was not judged and why (NaN state: the signals left out from then on).
    """

    episode: str  # the episode's name in the saved rollouts
    task: str
    step: int  # the frame judged (0: the reset's observation)
    rule: str
    scores: dict[str, float]
    threshold: float
    alarm: bool
    fired_views: tuple[str, ...]
    first_alarm: int | None  # the episode's first alarm so far
    nearest: NearestFailure | None = None  # at an alarm: the nearest failure and its cause
    skipped: tuple[str, ...] = ()
    stopped: str | None = None  # on_alarm="truncate": why the episode was cut (its action was not executed)
    blind_views: tuple[str, ...] = ()  # cameras that saw nothing at this step (black, one colour or NaN)
    usable: bool = True  # False: no view was judged, so `alarm=False` says nothing (docs/live.md)

    def to_dict(self) -> dict[str, Any]:
        """The verdict as plain JSON values."""
        return asdict(self)


def verdict_of(
    result: StepResult,
    *,
    episode: str,
    task: str,
    first_alarm: int | None,
    skipped: tuple[str, ...] = (),
) -> Verdict:
    """The verdict of a session's step (`DetectorSession.step`), the nearest failure only at an alarm."""
    nearest = None
    camera = result.camera_view if result.alarm else None
    if camera is not None and result.neighbors.get(camera):
        top = result.neighbors[camera][0]
        nearest = NearestFailure(
            view=camera,
            task=top.entry.task,
            episode=top.entry.episode,
            symbol=top.entry.symbol,
            cause=top.entry.description,
            similarity=float(top.similarity),
        )
    return Verdict(
        episode=episode,
        task=task,
        step=result.t,
        rule=result.rule.name,
        scores=dict(result.score),
        threshold=float(result.threshold),
        alarm=result.alarm,
        fired_views=tuple(result.fired_views),
        first_alarm=first_alarm,
        nearest=nearest,
        skipped=skipped,
        blind_views=tuple(result.blind_views),
        usable=result.usable,
    )
