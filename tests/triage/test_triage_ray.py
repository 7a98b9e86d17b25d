"""`triage --ray`: the episodes' frames encoded on a local Ray cluster, a batch of episodes per Ray Data
pass, give the ranking, curves and peaks of the triage run here (docs/ray.md)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_unlabelled_runs

from robofailring import CachedEncoder, load_dataset, load_encoder
from robofailring.data.model import Frame, Outcome
from robofailring.encoders.ray_backend import RayBackend
from robofailring.memory.builder import Provenance, build_memories
from robofailring.triage import TriageConfig, run_triage
from robofailring.triage import run as triage_run
from robofailring.triage.reference import MEMORY


@pytest.mark.slow  # a Ray cluster (session fixture) and a Ray Data pass per batch of episodes
def test_triage_on_ray_is_the_local_triage(
    ray_cluster: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    data, truth = write_unlabelled_runs(tmp_path / "runs", successes=6)  # 9 episodes
    known, _ = write_unlabelled_runs(tmp_path / "known", successes=4, failures=("grasp_wp2",))
    failed = {"outcome": Outcome.FAILURE, "symbol": "grasp_wp2"}
    labelled = [
        replace(t, **(failed if t.episode == "run_03" else {"outcome": Outcome.SUCCESS}))
        for t in load_dataset(known, task="pick_cube")
    ]
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "built")
    memory, _ = build_memories(labelled, encoder, provenance=Provenance(data=known, encoder="pixels"))
    folder = memory.save(tmp_path / "memory")
    passes: list[int] = []  # frames sent to the cluster, per Ray Data pass
    encode_all = RayBackend.encode_all

    def counted(self: RayBackend, frames: Sequence[Frame]) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        passes.append(len(frames))
        return encode_all(self, frames)

    monkeypatch.setattr(RayBackend, "encode_all", counted)
    monkeypatch.setattr(triage_run, "PREFETCH_EPISODES", 4)  # 9 episodes: batches of 4, 4 and 1
    results = {
        where: run_triage(
            TriageConfig(
                data=data,
                out=tmp_path / where,
                task="pick_cube",
                memory=folder,
                cache_dir=tmp_path / where,
                ray=ray,
            )
        )
        for where, ray in (("local", None), ("ray", "auto"))
    }
    local, on_ray = results["local"], results["ray"]
    assert len(passes) == 3 and min(passes) > 0  # one pass per batch of episodes, each frame sent once
    assert sum(passes) <= len(truth) * 2 * 6  # 2 views x 6 frames per episode
    assert on_ray.modes == {"pick_cube": MEMORY} and on_ray.ranked[0].rule == "contrast"
    assert [s.key for s in on_ray.ranked] == [s.key for s in local.ranked] and len(local.ranked) == len(truth)
    for mine, theirs in zip(on_ray.ranked, local.ranked, strict=True):
        np.testing.assert_allclose(mine.curve, theirs.curve, atol=1e-5)
        assert (mine.frame, mine.view, mine.normal_episode) == (
            theirs.frame,
            theirs.view,
            theirs.normal_episode,
        )
