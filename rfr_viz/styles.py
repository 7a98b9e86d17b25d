"""Every colour of a recording in one place: failure-type classes of the map, views, encoders, thresholds."""

from __future__ import annotations

from typing import Final

#: Failure types of grounding (Table 5) as map classes with fixed colours; class 0 is "unknown".
FAILURE_CLASSES: Final[dict[str, tuple[int, tuple[int, int, int]]]] = {
    "rotation": (1, (230, 85, 70)),
    "translation": (2, (70, 150, 240)),
    "grasp": (3, (250, 190, 40)),
    "slip": (4, (170, 110, 230)),
    "no_rotation": (5, (60, 200, 120)),
    "wrong_sequence": (6, (240, 120, 200)),
    "wrong_object": (7, (150, 210, 230)),
}
UNKNOWN_CLASS: Final[tuple[int, str, tuple[int, int, int]]] = (0, "unknown", (150, 150, 150))
VIEW_COLOURS: Final[tuple[tuple[int, int, int], ...]] = (
    (80, 160, 255),
    (90, 210, 110),
    (255, 160, 60),
    (200, 120, 255),
    (240, 220, 80),
)
MAP_FRAME_COLOUR: Final[tuple[int, int, int]] = (90, 90, 100)  # the box around each view's memory map
DELTA_COLOUR: Final[tuple[int, int, int]] = (235, 60, 60)
STATE_COLOUR: Final[tuple[int, int, int]] = (170, 170, 170)
STOP_COLOUR: Final[tuple[int, int, int]] = (235, 60, 60)  # the frame around a stopped robot's cameras
#: Few, large chunks: every chunk carries its own schema, so many small ones would dominate the file.
GAMMA_COLOUR: Final[tuple[int, int, int]] = (255, 120, 200)
ETA_COLOUR: Final[tuple[int, int, int]] = (120, 230, 230)
#: Each scoring rule's threshold line, by rule name; a rule not named here gets `OTHER_THRESHOLD_COLOUR`.
THRESHOLD_COLOURS: Final[dict[str, tuple[int, int, int]]] = {
    "paper": DELTA_COLOUR,
    "contrast": GAMMA_COLOUR,
    "novelty": ETA_COLOUR,
}
OTHER_THRESHOLD_COLOUR: Final[tuple[int, int, int]] = (240, 200, 90)


def threshold_colour(rule: str) -> tuple[int, int, int]:
    """The colour of a rule's threshold line, by rule name."""
    return THRESHOLD_COLOURS.get(rule, OTHER_THRESHOLD_COLOUR)
