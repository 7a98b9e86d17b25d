"""The monitor around a gymnasium vector env (issue 52, item 1): one session per sub-env, each sub-env's episodes
kept as they end while the others run, in every autoreset mode, with the alarms a single env gets."""

from __future__ import annotations

import json
from functools import partial
from pathlib import Path

import numpy as np
import pytest
from environment import require_module
from rollout_env import ADAPTER_SIGNALS, TEST_RUNS, ReplayEnv
from synthetic import VIEWS

from robofailring import FailureDetector, MappingAdapter, RolloutMonitor, VectorRolloutMonitor, load_dataset
from robofailring.errors import SettingError

gym = require_module("gymnasium", 'pip install "robofailring[gym]"')
ADAPTER = MappingAdapter(
    views={view: f"observation.images.{view}" for view in VIEWS}, signals=ADAPTER_SIGNALS
)
LENGTHS = (6, 8, 9, 7)  # each sub-env's episodes: so they end at different steps


def _sub_env(index: int) -> ReplayEnv:
    return ReplayEnv(TEST_RUNS[index:] + TEST_RUNS[:index], length=LENGTHS[index])


def _records(out: Path) -> list[dict[str, object]]:
    return json.loads((out / "episodes" / "manifest.json").read_text())["episodes"]


def _single(detector: FailureDetector, index: int, episodes: int, out: Path) -> list[tuple[object, ...]]:
    """What a single env under the monitor keeps of sub-env `index`'s first episodes."""
    with RolloutMonitor(_sub_env(index), detector, out=out, adapter=ADAPTER) as env:
        for _ in range(episodes):
            env.reset()
            while True:
                _, _, terminated, truncated, _ = env.step(env.unwrapped.expert_action())
                if terminated or truncated:
                    break
    return [(r["frames"], r["outcome"], r["monitor"]["alarm_frame"]) for r in _records(out)]


@pytest.mark.parametrize("mode", ["NextStep", "SameStep", "Disabled"])
def test_each_sub_env_s_episodes_are_kept_as_a_single_env_keeps_them(
    detector: FailureDetector, tmp_path: Path, mode: str
) -> None:
    envs = gym.vector.SyncVectorEnv([partial(_sub_env, i) for i in range(4)], autoreset_mode=mode)
    vector = VectorRolloutMonitor(envs, detector, out=tmp_path / "vector", adapter=ADAPTER)
    vector.reset(seed=0)
    seen: list[np.ndarray] = []
    for _ in range(20):
        actions = np.stack(envs.call("expert_action"))
        _, _, terminations, truncations, info = vector.step(actions)
        seen.append(info["_robofailring"])
        done = terminations | truncations
        if mode == "Disabled" and done.any():
            vector.reset(options={"reset_mask": done})
    vector.close()
    if mode == "NextStep":  # the step after a sub-env's end resets it: no verdict there
        assert not np.stack(seen).all()
    records = _records(tmp_path / "vector")
    for index, length in enumerate(LENGTHS):
        finished = [
            (r["frames"], r["outcome"], r["monitor"]["alarm_frame"])
            for r in records
            if r["monitor"]["ended"] == "terminated" and r["frames"] == length
        ]
        assert len(finished) >= 2
        assert finished == _single(detector, index, len(finished), tmp_path / f"single-{index}")
    closed = [r for r in records if r["monitor"]["ended"] == "closed"]
    assert len(closed) <= 4 and all(r["outcome"] is None for r in closed)
    assert len(list(load_dataset(tmp_path / "vector" / "episodes").trajectories())) == len(records)


def test_truncate_on_a_vector_env_needs_the_disabled_autoreset(
    detector: FailureDetector, tmp_path: Path
) -> None:
    envs = gym.vector.SyncVectorEnv([partial(_sub_env, i) for i in range(2)])
    with pytest.raises(SettingError, match="needs autoreset_mode=Disabled \\(this one's is NextStep\\)"):
        VectorRolloutMonitor(envs, detector, adapter=ADAPTER, on_alarm="truncate")
    envs = gym.vector.SyncVectorEnv([partial(_sub_env, i) for i in range(2)], autoreset_mode="Disabled")
    vector = VectorRolloutMonitor(envs, detector, out=tmp_path / "out", adapter=ADAPTER, on_alarm="truncate")
    vector.reset()
    _, _, terminations, truncations, info = vector.step(np.stack(envs.call("expert_action")))
    assert list(truncations) == [False, False]  # frame 0 of a failure and of a slip: no alarm yet
    _, _, terminations, truncations, info = vector.step(np.stack(envs.call("expert_action")))
    verdicts = info["robofailring"]
    assert list(truncations) == [True, True] and not terminations.any()  # both runs are failures
    assert all(v.stopped.endswith("the step's action was executed") for v in verdicts)
    vector.reset(options={"reset_mask": truncations})
    vector.step(np.stack(envs.call("expert_action")))  # the next episodes' first frames, judged
    vector.close()
    records = _records(tmp_path / "out")
    assert [(r["monitor"]["ended"], r["frames"]) for r in records] == [("alarm", 2)] * 2 + [("closed", 1)] * 2
