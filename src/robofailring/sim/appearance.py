"""Scene appearance: colours, object size, lighting and camera shift, in, out of distribution or random.

Three look modes: `in` (one fixed look), `ood` (three fixed palettes, shifted light and cameras:
the out-of-distribution test set's looks) and `random` (every colour, the light and the cameras
drawn from continuous ranges around and well beyond the in-distribution look, for training
encoders on variation; never within `OOD_MARGIN` of a fixed `ood` colour, so an OOD test stays
unseen).
"""

from __future__ import annotations

import colorsys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

import numpy as np

from robofailring.errors import SettingError

RGBA = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]

LOOK_MODES: Final[tuple[str, ...]] = ("in", "ood", "random")

#: In-distribution object colours: the target, the second object (stack base), the distractor.
_IN_COLOURS: tuple[RGBA, RGBA, RGBA] = (
    (0.85, 0.15, 0.10, 1.0),
    (0.15, 0.35, 0.85, 1.0),
    (0.95, 0.80, 0.10, 1.0),
)
#: Out-of-distribution palettes (target, second, distractor); one is drawn per episode.
_OOD_PALETTES: tuple[tuple[RGBA, RGBA, RGBA], ...] = (
    ((0.95, 0.45, 0.05, 1.0), (0.55, 0.20, 0.70, 1.0), (0.10, 0.75, 0.70, 1.0)),
    ((0.80, 0.10, 0.60, 1.0), (0.20, 0.65, 0.20, 1.0), (0.90, 0.90, 0.90, 1.0)),
    ((0.35, 0.85, 0.15, 1.0), (0.85, 0.55, 0.15, 1.0), (0.25, 0.25, 0.30, 1.0)),
)
_OOD_TABLES: tuple[RGBA, RGBA] = ((0.35, 0.38, 0.42, 1.0), (0.62, 0.64, 0.58, 1.0))  # warm, cool light
_OOD_TRAY: RGBA = (0.70, 0.60, 0.40, 1.0)
_OOD_GOAL: RGBA = (0.95, 0.95, 0.30, 1.0)
_OOD_LIGHTS: tuple[Vec3, Vec3] = ((1.0, 0.78, 0.55), (0.65, 0.8, 1.0))
#: Every fixed colour of the `ood` looks (RGB): a random look keeps at least OOD_MARGIN from each.
OOD_COLOURS: Final[tuple[Vec3, ...]] = (
    *(colour[:3] for palette in _OOD_PALETTES for colour in palette),
    *(colour[:3] for colour in (*_OOD_TABLES, _OOD_TRAY, _OOD_GOAL)),
    *_OOD_LIGHTS,
)
OOD_MARGIN: Final[float] = 0.1  # Euclidean distance in RGB, channels in [0, 1]

#: The `random` look's ranges, each drawn uniformly per episode. Colours are HSV (hue over the whole
#: circle); light direction components, strengths (pybullet's coefficients), the cameras' eye
#: offset (m; the overhead camera moves half as far, all keep the table's working area in view)
#: and the cube side (m; within what the grasp, the stack and the tray checks handle).
RANDOM_RANGES: Final[dict[str, tuple[float, float]]] = {
    "object_saturation": (0.2, 1.0),
    "object_value": (0.25, 1.0),
    "table_saturation": (0.0, 0.5),
    "table_value": (0.3, 0.95),
    "tray_saturation": (0.0, 0.7),
    "tray_value": (0.25, 0.9),
    "goal_saturation": (0.35, 1.0),
    "goal_value": (0.45, 1.0),
    "light_x": (-1.0, 1.0),
    "light_y": (-1.0, 1.0),
    "light_z": (0.3, 1.2),
    "light_channel": (0.6, 1.0),
    "ambient": (0.35, 0.8),
    "diffuse": (0.2, 0.75),
    "specular": (0.0, 0.3),
    "camera_x": (-0.12, 0.15),
    "camera_y": (-0.2, 0.2),
    "camera_z": (-0.1, 0.15),
    "cube_size": (0.03, 0.058),
}


@dataclass(frozen=True)
class Look:
    """Everything that changes how a scene looks but not what the controller is asked to do."""

    table_rgba: RGBA
    target_rgba: RGBA
    second_rgba: RGBA
    distractor_rgba: RGBA
    tray_rgba: RGBA
    goal_rgba: RGBA
    cube_size: float
    light_direction: Vec3
    light_color: Vec3
    ambient: float
    diffuse: float
    specular: float
    #: Offset added to the fixed cameras' eye positions (metres, world frame).
    camera_shift: Vec3
    mode: str  # one of LOOK_MODES


def look_mode(look: str, *, ood: bool) -> str:
    """The look mode asked for by `look` and the older `ood` flag (`ood=True` is ``look="ood"``)."""
    if look not in LOOK_MODES:
        raise SettingError(f"unknown look {look!r}; expected one of {list(LOOK_MODES)}")
    if ood and look == "random":
        raise SettingError("--ood and --look random contradict each other: pick one look")
    return "ood" if ood else look


def _in_look(rng: np.random.Generator) -> Look:
    return Look(
        table_rgba=(0.80, 0.70, 0.55, 1.0),
        target_rgba=_IN_COLOURS[0],
        second_rgba=_IN_COLOURS[1],
        distractor_rgba=_IN_COLOURS[2],
        tray_rgba=(0.45, 0.45, 0.50, 1.0),
        goal_rgba=(0.20, 0.75, 0.30, 1.0),
        cube_size=0.04,
        light_direction=(0.6, 0.3, 1.0),
        light_color=(1.0, 1.0, 1.0),
        ambient=0.6,
        diffuse=0.45,
        specular=0.05,
        camera_shift=(0.0, 0.0, 0.0),
        mode="in",
    )


def _ood_look(rng: np.random.Generator) -> Look:
    palette = _OOD_PALETTES[int(rng.integers(len(_OOD_PALETTES)))]
    warm = bool(rng.integers(2))
    side = float(rng.choice([-1.0, 1.0]))
    return Look(
        table_rgba=_OOD_TABLES[0] if warm else _OOD_TABLES[1],
        target_rgba=palette[0],
        second_rgba=palette[1],
        distractor_rgba=palette[2],
        tray_rgba=_OOD_TRAY,
        goal_rgba=_OOD_GOAL,
        cube_size=float(rng.uniform(0.048, 0.052)),
        light_direction=(float(rng.uniform(-1.0, -0.4)), side * float(rng.uniform(0.5, 1.0)), 0.6),
        light_color=_OOD_LIGHTS[0] if warm else _OOD_LIGHTS[1],
        ambient=0.45,
        diffuse=0.6,
        specular=0.15,
        camera_shift=(float(rng.uniform(0.05, 0.12)), side * float(rng.uniform(0.12, 0.2)), 0.12),
        mode="ood",
    )


def is_near_ood(rgb: tuple[float, ...]) -> bool:
    """Whether a colour lies within OOD_MARGIN of a fixed `ood` colour."""
    return any(float(np.linalg.norm(np.subtract(rgb[:3], fixed))) < OOD_MARGIN for fixed in OOD_COLOURS)


def _draw(rng: np.random.Generator, name: str) -> float:
    low, high = RANDOM_RANGES[name]
    return float(rng.uniform(low, high))


def _random_colour(rng: np.random.Generator, role: str) -> RGBA:
    """A colour of hue anywhere on the circle and the role's saturation and value ranges, redrawn
    while it lies near a fixed `ood` colour."""
    while True:
        hue = float(rng.uniform(0.0, 1.0))
        rgb = colorsys.hsv_to_rgb(hue, _draw(rng, f"{role}_saturation"), _draw(rng, f"{role}_value"))
        if not is_near_ood(rgb):
            return (*rgb, 1.0)


def _random_light(rng: np.random.Generator) -> Vec3:
    while True:
        colour = (_draw(rng, "light_channel"), _draw(rng, "light_channel"), _draw(rng, "light_channel"))
        if not is_near_ood(colour):
            return colour


def _random_look(rng: np.random.Generator) -> Look:
    return Look(
        table_rgba=_random_colour(rng, "table"),
        target_rgba=_random_colour(rng, "object"),
        second_rgba=_random_colour(rng, "object"),
        distractor_rgba=_random_colour(rng, "object"),
        tray_rgba=_random_colour(rng, "tray"),
        goal_rgba=_random_colour(rng, "goal"),
        cube_size=_draw(rng, "cube_size"),
        light_direction=(_draw(rng, "light_x"), _draw(rng, "light_y"), _draw(rng, "light_z")),
        light_color=_random_light(rng),
        ambient=_draw(rng, "ambient"),
        diffuse=_draw(rng, "diffuse"),
        specular=_draw(rng, "specular"),
        camera_shift=(_draw(rng, "camera_x"), _draw(rng, "camera_y"), _draw(rng, "camera_z")),
        mode="random",
    )


_LOOKS: Final[dict[str, Callable[[np.random.Generator], Look]]] = {
    "in": _in_look,
    "ood": _ood_look,
    "random": _random_look,
}


def make_look(mode: str, *, rng: np.random.Generator) -> Look:
    """The look of one episode: fixed `in` distribution, one of the `ood` palettes, or `random`."""
    return _LOOKS[mode](rng)
