"""`triage --ray`: the episodes' frames encoded on a local Ray cluster, a batch of episodes per Ray Data
pass, give the ranking, curves and peaks of the triage run here (docs/ray.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from synthetic import write_triage_memory, write_unlabelled_runs

from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.encoders.placement import EncoderPlacement
from robofailring.triage import TriageConfig, run_triage
from robofailring.triage import job as triage_job
from robofailring.triage.reference import MEMORY


@pytest.mark.slow  # a Ray cluster (session fixture) and a Ray Data pass per batch of episodes
def test_triage_on_ray_is_the_local_triage(
    ray_cluster: None, ray_passes: list[int], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    data, truth = write_unlabelled_runs(tmp_path / "runs", successes=6)  # 9 episodes
    folder = write_triage_memory(tmp_path / "built")
    monkeypatch.setattr(triage_job, "PREFETCH_EPISODES", 4)  # 9 episodes: batches of 4, 4 and 1
    results = {
        where: run_triage(
            TriageConfig(
                data=DataSelection(data, task="pick_cube"),
                out=tmp_path / where,
                detector=DetectorConfig(
                    memory=folder, placement=EncoderPlacement(cache_dir=tmp_path / where, ray=ray)
                ),
            )
        )
        for where, ray in (("local", None), ("ray", "auto"))
    }
    local, on_ray = results["local"], results["ray"]
    assert (
        len(ray_passes) == 3 and min(ray_passes) > 0
    )  # one pass per batch of episodes, each frame sent once
    assert sum(ray_passes) <= len(truth) * 2 * 6  # 2 views x 6 frames per episode
    assert on_ray.modes == {"pick_cube": MEMORY} and on_ray.ranked[0].rule == "contrast"
    assert [s.key for s in on_ray.ranked] == [s.key for s in local.ranked] and len(local.ranked) == len(truth)
    for mine, theirs in zip(on_ray.ranked, local.ranked, strict=True):
        np.testing.assert_allclose(mine.curve, theirs.curve, atol=1e-5)
        assert (mine.frame, mine.view, mine.normal_episode) == (
            theirs.frame,
            theirs.view,
            theirs.normal_episode,
        )
