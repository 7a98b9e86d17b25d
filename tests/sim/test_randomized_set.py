"""A simulated set under random looks: generated once per content, labelled like any generated set,
found again in its cache, and looking unlike the in-distribution scene (real physics)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robofailring.data.images import read_image
from robofailring.jobs.simulate import DataShape, extra_set
from robofailring.sim import KINDS, SUCCESS, run_episode

pytestmark = pytest.mark.slow  # simulation: the full lane only (scripts/test.sh)

SHAPE = DataShape(tasks=("pick_cube",), image_size=32, frames=4)


def test_a_randomized_set_is_simulated_once_and_found_again(tmp_path: Path) -> None:
    cache = tmp_path / "sets"
    first = extra_set(SHAPE, 8, look="random", seed=5000, workers=1, cache=cache)
    assert first.parent == cache and first.name.startswith("random-")
    manifest = json.loads((first / "manifest.json").read_text())
    assert manifest["look"] == "random" and manifest["config"]["look"] == "random"
    assert manifest["image_size"] == 32 and manifest["config"]["frames"] == 4
    records = manifest["episodes"]
    assert sorted(r["kind"] for r in records) == sorted(KINDS)  # 8 episodes: one per kind
    assert {r["split"] for r in records} == {"train", "test"}
    for record in records:
        assert record["retries"] == 0  # the unperturbed run reached its goal under its random look
        assert (record["outcome"] == "success") == (record["label"] is None)
        assert read_image(first / record["dir"] / "front_3.png").shape == (32, 32, 3)
    stamp = (first / "manifest.json").stat().st_mtime_ns
    assert extra_set(SHAPE, 8, look="random", seed=5000, workers=1, cache=cache) == first
    assert (first / "manifest.json").stat().st_mtime_ns == stamp  # found, not simulated again
    other = extra_set(SHAPE, 8, look="random", seed=5001, workers=1, cache=cache)
    control = extra_set(SHAPE, 8, look="in", seed=5000, workers=1, cache=cache)
    assert len({first, other, control}) == 3 and control.name.startswith("in-")
    success = next(r["dir"] for r in records if r["kind"] == SUCCESS)
    with run_episode("pick_cube", SUCCESS, 0, image_size=32, frames=2) as plain:
        in_view = next(iter(plain))["overhead"].astype(float)
    assert float(np.abs(read_image(first / success / "overhead_0.png") - in_view).mean()) > 10.0
