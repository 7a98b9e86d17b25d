"""A recording rendered in the real headless Rerun viewer: no viewer errors, and a picture with content."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from synthetic import write_episode

from rfr_viz.record import record_replay
from rfr_viz.viewer import ViewerUnavailable, check_vulkan, render_screenshot
from robofailring import (
    CachedEncoder,
    FailureDetector,
    FailureMemory,
    load_dataset,
    load_encoder,
    load_trajectory,
)

pytestmark = pytest.mark.viewer


@pytest.fixture(scope="module")
def viewer_ready() -> None:
    try:
        check_vulkan()
    except ViewerUnavailable as error:
        pytest.skip(f"headless Rerun viewer unavailable: {error}")


def test_replay_renders_in_the_real_viewer(viewer_ready: None, aha_dataset: Path, tmp_path: Path) -> None:
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    memory, _ = FailureMemory.build(load_dataset(aha_dataset), encoder)
    trajectory = load_trajectory(
        write_episode(tmp_path / "push_cube_slip_wp3_episode5", "push_cube", "slip_wp3")
    )
    first = FailureDetector(memory, encoder, k=3).run(trajectory)
    trace = first.with_delta(float(np.median(first.max_similarity())))
    assert trace.t_det is not None
    recording = record_replay(trajectory, trace, out=tmp_path / "replay.rrd")
    try:
        shot = render_screenshot(recording, tmp_path / "replay.png", frame=trace.t_det)
    except ViewerUnavailable as error:
        pytest.skip(f"headless Rerun viewer unavailable: {error}")
    assert shot.errors == [], shot.errors
    image = cv2.imread(str(shot.path), cv2.IMREAD_COLOR)
    assert image is not None and image.shape[1] >= 1280 and image.shape[0] >= 720
    assert float(image.std()) > 20.0, "the screenshot is blank"
    quantised = (image // 32).reshape(-1, 3)
    assert len(np.unique(quantised, axis=0)) >= 12, "too few distinct colours: panels did not draw"
    # the synthetic scene's yellow object is on screen (cameras and neighbour images are drawn)
    yellow = (image[:, :, 2] > 180) & (image[:, :, 1] > 170) & (image[:, :, 0] < 90)
    assert int(yellow.sum()) > 500


def test_missing_vulkan_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    import ctypes.util

    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    with pytest.raises(ViewerUnavailable, match="mesa-vulkan-drivers"):
        check_vulkan()
