"""Where a simulated failure starts: the first moment its perturbed plan departs from the nominal one,
and the first frame rendered after it (pure plan arithmetic, no physics)."""

from __future__ import annotations

import numpy as np
import pytest

from robofailring.sim.episode import frame_after, frame_steps
from robofailring.sim.perturb import Perturbation, apply, onset_time
from robofailring.sim.tasks import Layout, PickCube

# pick_cube's timeline: wp1 0–1.0 s, wp2 1.0–1.8 s (closes on arrival, holds 0.4 s), wp3 from 2.2 s (0.9 s)
LAYOUT = Layout(bodies={}, starts={"target": (0.5, -0.06, 0.3), "distractor": (0.56, 0.15, -0.2)}, size=0.04)


@pytest.mark.parametrize(
    ("perturbation", "seconds"),
    [
        (Perturbation("grasp", 2), 1.8),  # the gripper does not close when wp2 is reached
        (Perturbation("slip", 3), 2.2 + 0.5 * 0.9),  # the grasp opens half-way to wp3
        (Perturbation("translation_x", 2), 1.0),  # the motion to the shifted wp2 starts off course
        (Perturbation("rotation_z", 2), 1.0),
        (Perturbation("no_rotation", 1), 0.0),  # the turn towards the cube is skipped from the start
        (Perturbation("wrong_sequence", 2), 0.0),  # wp2's pose is visited in wp1's slot
    ],
)
def test_onset_is_the_first_moment_the_plans_differ(perturbation: Perturbation, seconds: float) -> None:
    task = PickCube()
    nominal = task.plan(LAYOUT)
    assert onset_time(nominal, apply(nominal, perturbation)) == pytest.approx(seconds)


def test_wrong_object_starts_at_once_and_an_unperturbed_plan_never() -> None:
    task = PickCube()
    nominal = task.plan(LAYOUT)
    assert onset_time(nominal, task.plan(LAYOUT, obj="distractor")) == 0.0
    assert onset_time(nominal, apply(nominal, None)) is None


def test_onset_frame_is_the_first_frame_rendered_after_it() -> None:
    steps = frame_steps(40)  # 40 frames over 6 s at 240 Hz: frame i at step round(i · 1440 / 39)
    assert frame_after(steps, 1.8) == 12  # step 432: frame 11 is at step 406, frame 12 at 443
    assert steps[11] <= 432 < steps[12]
    assert frame_after(steps, 0.0) == 1  # frame 0 shows the scene before any command acted
    assert frame_after(steps, None) is None and frame_after(steps, 6.0) is None
    assert np.all(np.diff(steps) > 0)
