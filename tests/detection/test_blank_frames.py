"""Silent false alarms (issue 35, item 8): a frame the encoder sees as nothing never matches, and a
detector judging at a default threshold says so."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.detection.rules import CONTRAST
from robofailring.detection.threshold_policy import ThresholdPolicy
from robofailring.evaluation.calibration import CalibrateConfig, calibrate
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
            detector=DetectorConfig(cache_dir=tmp_path / "c"),
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
    steps = [blank_start.step(black)] + [blank_start.step(images) for images in frames[1:3]]
    assert not any(step.alarm for step in steps)  # no first frame to compare with: nothing is scored
    assert all(np.isnan(value) for step in steps for value in step.score.values())
    session = detector.session(trajectory.task)
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
        detector=DetectorConfig(memory=memory_dir, cache_dir=tmp_path / "c"),
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
            detector=DetectorConfig(memory=memory_dir, cache_dir=tmp_path / "c"),
            thresholds=ThresholdPolicy(target_fpr=0.5),
        )
    )
    with caplog.at_level(logging.WARNING, logger="robofailring"):
        run_detect(config)
        run_detect(
            DetectConfig(
                data=DataSelection(data),
                detector=DetectorConfig(
                    memory=memory_dir, cache_dir=tmp_path / "c", thresholds={"contrast": 0.1}
                ),
                key=key,
            )
        )
    assert not [r for r in caplog.records if "not calibrated" in r.getMessage()]
