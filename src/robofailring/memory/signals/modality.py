"""The one home of the modalities: what a detector judges by (`--modality`), the view the robot's signals are
scored as beside the camera views, the groups a `per-modality` fusion bands, and the one split of views between
the cameras and the signals. The names are equal strings, but each says something else ("signals" names a
modality, a view and a fusion group), so each has its own constant; `tests/architecture/test_one_home.py` keeps
them here.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final, NamedTuple

# What a detector judges by (`--modality`): the cameras and the robot's signals fused (where the memory has
# signals), the cameras alone, or the signals alone; also what a calibration's thresholds judge.
BOTH: Final[str] = "both"
CAMERAS: Final[str] = "cameras"
SIGNALS: Final[str] = "signals"
MODALITIES: Final[tuple[str, ...]] = (BOTH, CAMERAS, SIGNALS)

# The view the robot's signals are scored as, fused with the camera views (a trace's, a step's, a band's view).
SIGNALS_VIEW: Final[str] = "signals"

# The groups of views a `per-modality` fusion fits a band each for (robofailring.calibration.fusions): the camera
# views' max, and the signals view (whose band is kept as the band's view `SIGNALS_VIEW`).
CAMERAS_GROUP: Final[str] = "cameras"
SIGNALS_GROUP: Final[str] = "signals"
FUSION_GROUPS: Final[tuple[str, ...]] = (CAMERAS_GROUP, SIGNALS_GROUP)


class SplitViews(NamedTuple):
    """Views split by modality, each in the order given: the camera views, and the signals view (if given)."""

    cameras: list[str]
    signals: list[str]


def split_views(views: Iterable[str]) -> SplitViews:
    """`views` (camera views and, where scored, `SIGNALS_VIEW`) split into the cameras and the signals."""
    given = list(views)
    return SplitViews(
        [view for view in given if view != SIGNALS_VIEW], [view for view in given if view == SIGNALS_VIEW]
    )


def judged_views(views: Iterable[str], modality: str) -> list[str]:
    """The views of `views` that `modality` judges, in their order: every one for `BOTH`, the camera views for
    `CAMERAS`, the signals view for `SIGNALS`."""
    given = list(views)
    if modality == BOTH:
        return given
    split = split_views(given)
    return split.signals if modality == SIGNALS else split.cameras
