"""The simulator's look modes: random looks drawn within their ranges, away from the OOD test's
colours, per seed; the look mode in GenerateConfig without changing the in/ood sets' cache keys."""

from __future__ import annotations

import colorsys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robofailring.errors import SettingError
from robofailring.sim import GenerateConfig
from robofailring.sim.appearance import OOD_COLOURS, OOD_MARGIN, RANDOM_RANGES, Look, look_mode, make_look

SEEDS = range(300)
COLOUR_ROLES = {
    "target_rgba": "object",
    "second_rgba": "object",
    "distractor_rgba": "object",
    "table_rgba": "table",
    "tray_rgba": "tray",
    "goal_rgba": "goal",
}


def _random(seed: int) -> Look:
    return make_look("random", rng=np.random.default_rng(seed))


def _within(value: float, name: str) -> bool:
    low, high = RANDOM_RANGES[name]
    return low - 1e-9 <= value <= high + 1e-9


def test_random_looks_stay_within_their_ranges() -> None:
    for seed in SEEDS:
        look = _random(seed)
        assert look.mode == "random"
        for field, role in COLOUR_ROLES.items():
            rgba = getattr(look, field)
            _, saturation, value = colorsys.rgb_to_hsv(*rgba[:3])
            assert rgba[3] == 1.0
            assert _within(saturation, f"{role}_saturation") and _within(value, f"{role}_value"), (
                seed,
                field,
            )
        assert all(_within(c, "light_channel") for c in look.light_color)
        for component, axis in zip(look.light_direction, "xyz", strict=True):
            assert _within(component, f"light_{axis}")
        for component, axis in zip(look.camera_shift, "xyz", strict=True):
            assert _within(component, f"camera_{axis}")
        for name in ("ambient", "diffuse", "specular", "cube_size"):
            assert _within(getattr(look, name), name), (seed, name)


def test_random_looks_span_their_ranges_and_differ_per_seed() -> None:
    looks = [_random(seed) for seed in SEEDS]
    assert _random(7) == looks[7]  # the same seed, the same look
    assert len({look.target_rgba for look in looks}) == len(looks)
    assert len({look.camera_shift for look in looks}) == len(looks)
    hues = [colorsys.rgb_to_hsv(*look.target_rgba[:3])[0] for look in looks]
    assert np.histogram(hues, bins=6, range=(0.0, 1.0))[0].min() > 0  # every hue sextant drawn
    for name in ("cube_size", "ambient", "diffuse"):
        low, high = RANDOM_RANGES[name]
        drawn = [getattr(look, name) for look in looks]
        assert min(drawn) < low + 0.1 * (high - low) and max(drawn) > high - 0.1 * (high - low), name
    shifts = np.asarray([look.camera_shift for look in looks])
    assert (shifts.min(axis=0) < 0).all() and (shifts.max(axis=0) > 0).all()  # both ways on every axis


def test_random_colours_keep_away_from_every_fixed_ood_colour() -> None:
    fixed = np.asarray(OOD_COLOURS)
    ood = make_look("ood", rng=np.random.default_rng(0))
    assert ood.target_rgba[:3] in OOD_COLOURS and ood.light_color in OOD_COLOURS  # the list holds them
    for seed in SEEDS:
        look = _random(seed)
        colours = [getattr(look, field)[:3] for field in COLOUR_ROLES] + [look.light_color]
        distances = np.linalg.norm(np.asarray(colours)[:, None, :] - fixed[None, :, :], axis=2)
        assert distances.min() >= OOD_MARGIN, seed


def test_in_and_ood_looks_are_unchanged_by_the_random_mode() -> None:
    assert make_look("in", rng=np.random.default_rng(3)) == make_look("in", rng=np.random.default_rng(4))
    ood = make_look("ood", rng=np.random.default_rng(3))
    assert ood.mode == "ood" and 0.048 <= ood.cube_size <= 0.052 and ood.camera_shift[2] == 0.12


def test_look_mode_in_generate_config(tmp_path: Path) -> None:
    plain = GenerateConfig(out=tmp_path)
    assert (plain.look, plain.ood) == ("in", False)
    assert GenerateConfig(out=tmp_path, ood=True).look == "ood"
    assert GenerateConfig(out=tmp_path, look="ood").ood is True
    assert replace(plain, ood=True).look == "ood"  # how the demo and the benches derive their OOD sets
    randomized = GenerateConfig(out=tmp_path, look="random", seed=5000)
    assert randomized.ood is False and randomized.content()["look"] == "random"
    # in and ood sets keep the cache key they had before look modes existed
    assert "look" not in plain.content() and "look" not in GenerateConfig(out=tmp_path, ood=True).content()
    assert randomized.content() != replace(randomized, look="in").content()
    with pytest.raises(SettingError, match="contradict"):
        GenerateConfig(out=tmp_path, look="random", ood=True)
    with pytest.raises(SettingError, match="unknown look 'noir'"):
        look_mode("noir", ood=False)
