"""Scene appearance: colours, object size, lighting and camera shift, in and out of distribution."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RGBA = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]

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
    ood: bool


def make_look(*, ood: bool, rng: np.random.Generator) -> Look:
    """The look of one episode: fixed in distribution, drawn from shifted ranges when `ood`."""
    if not ood:
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
            ood=False,
        )
    palette = _OOD_PALETTES[int(rng.integers(len(_OOD_PALETTES)))]
    warm = bool(rng.integers(2))
    side = float(rng.choice([-1.0, 1.0]))
    return Look(
        table_rgba=(0.35, 0.38, 0.42, 1.0) if warm else (0.62, 0.64, 0.58, 1.0),
        target_rgba=palette[0],
        second_rgba=palette[1],
        distractor_rgba=palette[2],
        tray_rgba=(0.70, 0.60, 0.40, 1.0),
        goal_rgba=(0.95, 0.95, 0.30, 1.0),
        cube_size=float(rng.uniform(0.048, 0.052)),
        light_direction=(float(rng.uniform(-1.0, -0.4)), side * float(rng.uniform(0.5, 1.0)), 0.6),
        light_color=(1.0, 0.78, 0.55) if warm else (0.65, 0.8, 1.0),
        ambient=0.45,
        diffuse=0.6,
        specular=0.15,
        camera_shift=(float(rng.uniform(0.05, 0.12)), side * float(rng.uniform(0.12, 0.2)), 0.12),
        ood=True,
    )
