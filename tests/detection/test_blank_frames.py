"""Silent false alarms (issue 35, item 8): a frame the encoder sees as nothing never matches, and a
detector judging at a default threshold says so."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_project_dataset

import robofailring as rfr
from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.calibration.job import CalibrateConfig, calibrate
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.detection.rules import CONTRAST
from robofailring.encoders.placement import EncoderPlacement
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.jobs.detect import DetectConfig, run_detect
from robofailring.memory.recipe import MemoryRecipe


@pytest.fixture()
def both(tmp_path: Path) -> tuple[Path, Path, CachedEncoder]:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=4)
    build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=tmp_path / "m",
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=tmp_path / "c"),
            split="train",
        )
    )
    return data, tmp_path / "m", CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "c")


def test_an_all_black_frame_matches_nothing_at_any_threshold(both: tuple[Path, Path, CachedEncoder]) -> None:
    data, memory_dir, encoder = both
    memory = FailureMemory.load(memory_dir)
    trajectory = load_dataset(data).select(split="test")[0]
    views = list(trajectory.views)
    frames = [{view: trajectory.views[view][t].load() for view in views} for t in range(trajectory.length)]
    black = {view: np.zeros_like(image) for view, image in frames[0].items()}
    assert not np.linalg.norm(encoder.encoder.encode([black[views[0]]]))  # the pixels encoder sees nothing
    # the lowest contrast threshold there is: every scored frame reaches it, a blank one never does
    detector = FailureDetector(memory, encoder, rule="contrast", gamma=-2.0)
    blank_start = detector.session(trajectory.task)
    with pytest.warns(rfr.BlindCameraWarning):
        steps = [blank_start.step(black)] + [blank_start.step(images) for images in frames[1:3]]
    assert not any(step.alarm for step in steps)  # no first frame to compare with: nothing is scored
    assert all(np.isnan(value) for step in steps for value in step.score.values())
    session = detector.session(trajectory.task)
    with pytest.warns(rfr.BlindCameraWarning):
        first, blank, after = session.step(frames[0]), session.step(black), session.step(frames[1])
    assert first.alarm and after.alarm and not blank.alarm
    assert all(np.isnan(value) for value in blank.score.values())
    assert all(np.isnan(value) for value in blank.similarity.values())
    assert all(not found for found in blank.neighbors.values())
    assert all(np.isfinite(value) for value in after.score.values())


def test_detect_says_when_its_rule_judges_at_an_uncalibrated_default(
    both: tuple[Path, Path, CachedEncoder], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    data, memory_dir, _ = both
    key = load_dataset(data).select(split="test")[0].key
    config = DetectConfig(
        data=DataSelection(data),
        detector=DetectorConfig(memory=memory_dir, placement=EncoderPlacement(cache_dir=tmp_path / "c")),
        key=key,
    )
    with caplog.at_level(logging.WARNING, logger="robofailring"):
        assert run_detect(config).trace.rule is CONTRAST
    said = [r.getMessage() for r in caplog.records if "not calibrated" in r.getMessage()]
    assert len(said) == 1 and "the contrast rule judges at its default γ = 0" in said[0]
    assert "robofailring calibrate" in said[0] and "--gamma" in said[0]
    caplog.clear()
    calibrate(
        CalibrateConfig(
            data=DataSelection(data),
            memory=memory_dir,
            placement=EncoderPlacement(cache_dir=tmp_path / "c"),
            threshold_policy=ThresholdPolicy(target_fpr=0.5),
        )
    )
    with caplog.at_level(logging.WARNING, logger="robofailring"):
        run_detect(config)
        run_detect(
            DetectConfig(
                data=DataSelection(data),
                detector=DetectorConfig(
                    memory=memory_dir,
                    thresholds={"contrast": 0.1},
                    placement=EncoderPlacement(cache_dir=tmp_path / "c"),
                ),
                key=key,
            )
        )
    assert not [r for r in caplog.records if "not calibrated" in r.getMessage()]


class _NotANumber:
    """An encoder that returns NaN for the frames it is told are broken (a driver's NaN, a model's
    overflow), the pixels encoder's numbers for the others."""

    def __init__(self, inner: CachedEncoder, broken: set[int]) -> None:
        self.inner, self.broken, self.calls = inner.encoder, broken, 0

    identity = property(lambda self: self.inner.identity)
    dim = property(lambda self: self.inner.dim)

    def encode(self, images: list[np.ndarray]) -> np.ndarray:
        found = np.array(self.inner.encode(images), dtype=np.float32)
        if self.calls in self.broken:
            found[:] = np.nan
        self.calls += 1
        return found


def test_a_blind_live_step_says_so_and_warns_once_per_view(both: tuple[Path, Path, CachedEncoder]) -> None:
    """Issue 50: a black or NaN frame is never a silent `alarm=False`: the step names its blind views,
    says it judged nothing (`usable`), and one BlindCameraWarning per view tells the robot loop."""
    data, memory_dir, encoder = both
    trajectory = load_dataset(data).select(split="test")[0]
    views = list(trajectory.views)
    frames = [{view: trajectory.views[view][t].load() for view in views} for t in range(trajectory.length)]
    detector = FailureDetector(FailureMemory.load(memory_dir), encoder, rule="contrast", gamma=-2.0)
    session = detector.session(trajectory.task)
    black = dict(frames[2]) | {views[0]: np.zeros_like(frames[2][views[0]])}
    nan = {view: np.full(image.shape, np.nan, np.float32) for view, image in frames[3].items()}
    with pytest.warns(rfr.BlindCameraWarning) as warned:
        steps = [session.step(frames[0]), session.step(frames[1]), session.step(black), session.step(nan)]
        steps += [session.step(black)]
    assert [step.blind_views for step in steps] == [[], [], [views[0]], views, [views[0]]]
    assert [step.usable for step in steps] == [True, True, True, False, True]
    assert not steps[3].alarm and all(np.isnan(value) for value in steps[3].score.values())
    assert sorted(str(w.message).split(" view ")[1].split(":")[0] for w in warned) == sorted(views)
    assert "frame 2 is blank to the encoder" in str(warned[0].message)
    assert session.blind_steps == {views[0]: [2, 3, 4], **{view: [3] for view in views[1:]}}


def test_nan_embeddings_are_never_counted_as_usable(both: tuple[Path, Path, CachedEncoder]) -> None:
    """An encoder's NaN rows are blind, live and offline: not scored, never a neighbour, and said."""
    data, memory_dir, encoder = both
    trajectory = load_dataset(data).select(split="test")[0]
    views = list(trajectory.views)
    frames = [{view: trajectory.views[view][t].load() for view in views} for t in range(trajectory.length)]
    broken = CachedEncoder(_NotANumber(encoder, {1}), cache_dir=None)  # type: ignore[arg-type]
    detector = FailureDetector(FailureMemory.load(memory_dir), broken, rule="contrast", gamma=-2.0)
    session = detector.session(trajectory.task)
    with pytest.warns(rfr.BlindCameraWarning):
        steps = [session.step(images) for images in frames[:3]]
    assert [step.usable for step in steps] == [True, False, True]
    assert steps[1].blind_views == views and not steps[1].alarm
    assert all(not found for found in steps[1].neighbors.values())
    assert all(np.isfinite(value) for value in steps[2].score.values())
