"""`evaluate --ray`: the memory built, the thresholds calibrated and every test run scored from embeddings
encoded on a local Ray cluster are those of the evaluation run here (docs/ray.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.evaluation.job import EvaluateConfig, run_evaluation


@pytest.mark.slow  # a Ray cluster (session fixture) and three Ray Data passes
def test_evaluation_on_ray_is_the_local_evaluation(
    ray_cluster: None, ray_passes: list[int], tmp_path: Path
) -> None:
    dataset = write_project_dataset(tmp_path / "data")
    results = {
        where: run_evaluation(
            EvaluateConfig(
                data=DataSelection(dataset),
                threshold_policy=ThresholdPolicy(target_fpr=0.2),
                out=tmp_path / where,
                placement=EncoderPlacement(cache_dir=tmp_path / f"cache-{where}", ray=ray),
            )
        )
        for where, ray in (("local", None), ("ray", "auto"))
    }
    local, on_ray = results["local"], results["ray"]
    assert len(ray_passes) == 3 and min(ray_passes) > 0  # the failure memory, the success memory, the replays
    assert [s.key for s in on_ray.scored] == [s.key for s in local.scored] and local.scored
    for mine, theirs in zip(on_ray.scored, local.scored, strict=True):
        assert mine.similarity.keys() == theirs.similarity.keys()
        for view in mine.similarity:
            np.testing.assert_allclose(mine.similarity[view], theirs.similarity[view], atol=1e-5)
    assert on_ray.rules.keys() == local.rules.keys()
    for name, rule in on_ray.rules.items():
        assert rule.threshold == pytest.approx(local.rules[name].threshold, abs=1e-5)
        assert (rule.tp, rule.fp, rule.fn, rule.tn) == (
            local.rules[name].tp,
            local.rules[name].fp,
            local.rules[name].fn,
            local.rules[name].tn,
        )
