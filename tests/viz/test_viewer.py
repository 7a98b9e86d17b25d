"""A recording rendered in the real headless Rerun viewer: no viewer errors, and a picture with content."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from environment import require_viewer, viewer_available
from ports import free_port
from synthetic import write_episode, write_project_dataset

from rfr_viz.recordings.blueprint import FOCUS_MARGIN
from rfr_viz.recordings.evaluation import record_evaluation
from rfr_viz.recordings.replay import record_replay
from rfr_viz.viewer.binary import ViewerUnavailable, check_vulkan
from rfr_viz.viewer.control import open_at, playback_positions, render_screenshot
from rfr_viz.viewer.rrd import focus_frame
from robofailring import (
    CachedEncoder,
    DetectionTrace,
    FailureDetector,
    FailureMemory,
    load_encoder,
    load_trajectory,
)
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.model import Trajectory
from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.evaluation.job import EvaluateConfig, run_evaluation

pytestmark = pytest.mark.viewer


@pytest.fixture(scope="module")
def viewer_ready() -> None:
    require_viewer()


def test_replay_renders_in_the_real_viewer(
    viewer_ready: None, pixels_memory: FailureMemory, tmp_path: Path
) -> None:
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    trajectory = load_trajectory(
        write_episode(tmp_path / "push_cube_slip_wp3_episode5", "push_cube", "slip_wp3")
    )
    first = FailureDetector(pixels_memory, encoder, k=3).run(trajectory)
    trace = first.with_delta(float(np.median(first.max_similarity())))
    assert trace.t_det is not None
    recording = record_replay(trajectory, trace, out=tmp_path / "replay.rrd")
    with viewer_available():
        shot = render_screenshot(recording, tmp_path / "replay.png", frame=trace.t_det)
    assert shot.errors == [], shot.errors
    image = cv2.imread(str(shot.path), cv2.IMREAD_COLOR)
    assert image is not None and image.shape[1] >= 1280 and image.shape[0] >= 720
    assert float(image.std()) > 20.0, "the screenshot is blank"
    quantised = (image // 32).reshape(-1, 3)
    assert len(np.unique(quantised, axis=0)) >= 12, "too few distinct colours: panels did not draw"
    # the synthetic scene's yellow object is on screen (cameras and neighbour images are drawn)
    yellow = (image[:, :, 2] > 180) & (image[:, :, 1] > 170) & (image[:, :, 0] < 90)
    assert int(yellow.sum()) > 500


def _success_replay(
    memory: FailureMemory, tmp_path: Path, *, length: int
) -> tuple[Trajectory, DetectionTrace]:
    """A success episode of `length` frames scored against the AHA fixture's memory (K = 2)."""
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    trajectory = load_trajectory(
        write_episode(tmp_path / "pick_cube_success_episode9", "pick_cube", None, length=length)
    )
    return trajectory, FailureDetector(memory, encoder, k=2).run(trajectory)


def test_a_review_recording_plays_around_its_alarm(
    viewer_ready: None, pixels_memory: FailureMemory, tmp_path: Path
) -> None:
    """Opened without seeking, a recording with a focus frame reaches the alarm and loops there."""
    trajectory, trace = _success_replay(pixels_memory, tmp_path, length=36)
    focus = 26
    recording = record_replay(trajectory, trace, out=tmp_path / "alarm.rrd", focus_frame=focus)
    positions = [p for p in playback_positions(recording, seconds=12.0, interval=0.15) if p is not None]
    window = range(focus - FOCUS_MARGIN, focus + FOCUS_MARGIN + 1)
    assert positions, "the viewer reported no time cursor"
    entered = next((i for i, p in enumerate(positions) if p in window), None)
    assert entered is not None, f"playback never reached frames {window.start}-{window.stop - 1}: {positions}"
    after = positions[entered:]
    assert len(after) >= 5 and all(p in window for p in after), positions
    assert len(set(after)) >= 3, f"the cursor does not move inside the window: {after}"


def test_open_pauses_at_the_alarm_and_reuses_a_running_viewer(
    viewer_ready: None, pixels_memory: FailureMemory, tmp_path: Path
) -> None:
    trajectory, trace = _success_replay(pixels_memory, tmp_path, length=30)
    alarm = record_replay(trajectory, trace, out=tmp_path / "alarm.rrd", focus_frame=17)
    plain = record_replay(trajectory, trace.with_delta(1.0), out=tmp_path / "plain.rrd")
    assert focus_frame(alarm) == 17 and focus_frame(plain) == 0  # no focus, no detection: the start

    from rerun.experimental import ViewerClient

    port = free_port()
    first = open_at(alarm, port=port, headless=True)
    try:
        assert first.process is not None and first.frame == 17
        second = open_at(plain, 9, port=port, headless=True)  # reuses the running viewer
        assert second.process is None and second.frame == 9
        state = ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy").get_state()
        shown = {r.store_id: (r.current_timeline, r.current_time) for r in state.recordings}
        assert sorted(shown.values()) == [("frame", 9), ("frame", 17)], shown
    finally:
        first.close()
    assert first.process.poll() is not None  # the viewer started for it is stopped


def test_a_recording_without_a_frame_timeline_renders(viewer_ready: None, tmp_path: Path) -> None:
    """The evaluation summary is indexed by δ, not by frame: it still opens and renders."""
    data = write_project_dataset(tmp_path / "data")
    result = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data),
            threshold_policy=ThresholdPolicy(target_fpr=0.2),
            placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
            out=tmp_path / "eval",
        )
    )
    assert set(result.rules) == {"paper", "contrast", "novelty"}  # every rule's operating point is drawn
    recording = record_evaluation([result], out=tmp_path / "evaluation.rrd")
    shot = render_screenshot(recording, tmp_path / "evaluation.png", settle=1.0)
    assert shot.errors == [], shot.errors
    image = cv2.imread(str(shot.path), cv2.IMREAD_COLOR)
    assert image is not None and float(image.std()) > 20.0
    with pytest.raises(ValueError, match="no 'frame' timeline"):
        render_screenshot(recording, tmp_path / "frame.png", frame=3)


def test_missing_vulkan_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    import ctypes.util

    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    with pytest.raises(ViewerUnavailable, match="mesa-vulkan-drivers"):
        check_vulkan()
