"""Jobs pass values: an evaluation takes a detector already loaded and keeps each run's trace with its `place`
rows, so a recording needs no second scoring; an encoder comparison takes a result it is given."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring import load_dataset
from robofailring.data.selection import DataSelection
from robofailring.detection.detector import Place
from robofailring.detection.loader import detector_from
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import SettingError
from robofailring.evaluation.job import EvaluateConfig, build_training_memory, run_evaluation
from robofailring.jobs.compare_encoders import CompareEncodersConfig, compare_encoders


def _first_columns(task: str) -> Place:
    """A `place` hook: each query's first two numbers (a stand-in for a map's 2-D point)."""
    return lambda view, queries: np.asarray(queries[:, :2], dtype=np.float32)


def test_an_evaluation_takes_a_loaded_detector_and_keeps_placed_traces(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", episodes=4)
    config = EvaluateConfig(
        data=DataSelection(data),
        threshold_policy=None,
        out=tmp_path / "out",
        placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
    )
    memory_dir, _ = build_training_memory(config)
    stored = replace(config, memory=memory_dir)
    detector = detector_from(stored.detector)

    given = run_evaluation(stored, detector=detector, place=_first_columns)
    loaded = run_evaluation(stored)  # the same evaluation, loading the memory itself
    assert Path(given.memory).resolve() == Path(loaded.memory).resolve() == memory_dir.resolve()
    assert given.to_dict()["rules"] == loaded.to_dict()["rules"]
    trajectories = {t.key: t for t in load_dataset(data).trajectories()}
    for key, trace in given.traces.items():
        assert trace.memory is detector.memory  # not loaded again
        again = detector.run(trajectories[key])
        for view in trace.views:
            np.testing.assert_array_equal(trace.similarity[view], loaded.traces[key].similarity[view])
            np.testing.assert_allclose(trace.placed[view], again.queries[view][:, :2], atol=1e-6)
        assert not loaded.traces[key].placed


CLIP = "open_clip:ViT-B-32:openai"  # a second encoder by name: its weights are never needed here


def test_an_encoder_comparison_takes_the_results_it_is_given(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", episodes=4)
    cache = EncoderPlacement(cache_dir=tmp_path / "cache")
    headline = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data), threshold_policy=None, out=tmp_path / "eval", placement=cache
        )
    )
    out = tmp_path / "encoders"
    config = CompareEncodersConfig(
        data=DataSelection(data), out=out, encoders=("pixels", CLIP), placement=cache
    )
    results = compare_encoders(config, existing={"pixels": headline, CLIP: headline})  # never loaded
    assert results == [headline, headline] and not out.exists()  # nothing built, calibrated or scored again
    with pytest.raises(SettingError, match="at least two encoders"):
        compare_encoders(replace(config, encoders=("pixels",)), existing={"pixels": headline})
