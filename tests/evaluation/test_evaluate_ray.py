"""`evaluate --ray`: the memory built, the thresholds calibrated and every test run scored from embeddings
encoded on a local Ray cluster are those of the evaluation run here (docs/ray.md)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring.data.model import Frame
from robofailring.detection.config import DetectorConfig
from robofailring.encoders.ray_backend import RayBackend
from robofailring.evaluation.run import EvaluateConfig, run_evaluation


@pytest.mark.slow  # a Ray cluster (session fixture) and three Ray Data passes
def test_evaluation_on_ray_is_the_local_evaluation(
    ray_cluster: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    dataset = write_project_dataset(tmp_path / "data")
    passes: list[int] = []  # frames sent to the cluster, per Ray Data pass
    encode_all = RayBackend.encode_all

    def counted(self: RayBackend, frames: Sequence[Frame]) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        passes.append(len(frames))
        return encode_all(self, frames)

    monkeypatch.setattr(RayBackend, "encode_all", counted)
    results = {
        where: run_evaluation(
            EvaluateConfig(
                data=dataset,
                out=tmp_path / where,
                detector=DetectorConfig(cache_dir=tmp_path / f"cache-{where}"),
                target_fpr=0.2,
                ray=ray,
            )
        )
        for where, ray in (("local", None), ("ray", "auto"))
    }
    local, on_ray = results["local"], results["ray"]
    assert len(passes) == 3 and min(passes) > 0  # the failure memory, the success memory, the replays
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
