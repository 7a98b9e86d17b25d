"""The embedded simulator as a gymnasium env under the monitor, end to end (issue 52, items 3 and 5): its
scripted policy's rollouts judged, kept with the goal check as the outcome, a live `.rrd` per episode, and the
saved rollouts opened by `replay` and judged by `detect` as the monitor judged them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rrd import properties
from typer.testing import CliRunner

from rfr_viz import monitor_recorder
from rfr_viz.cli.app import app
from robofailring import (
    SIM_ADAPTER,
    CachedEncoder,
    FailureMemory,
    GenerateConfig,
    RolloutMonitor,
    SimEnv,
    generate_dataset,
    load_dataset,
    open_detector,
)

pytestmark = pytest.mark.slow  # simulation: the full lane

TASK, SIZE, FRAMES = "pick_cube", 48, 12


@pytest.fixture(scope="module")
def sim_memory(tmp_path_factory: pytest.TempPathFactory, encoder: CachedEncoder) -> Path:
    config = GenerateConfig(
        out=tmp_path_factory.mktemp("sim") / "data",
        tasks=(TASK,),
        modes=("success", "grasp"),
        episodes=2,
        image_size=SIZE,
        frames=FRAMES,
        workers=1,
    )
    built, _ = FailureMemory.build(load_dataset(generate_dataset(config)).trajectories(), encoder)
    return built.save(tmp_path_factory.mktemp("sim-memory") / "memory")


def test_the_simulator_s_rollouts_are_judged_kept_recorded_and_replayed(
    sim_memory: Path, tmp_path: Path
) -> None:
    detector = open_detector(sim_memory)
    env = SimEnv(TASK, modes=("grasp", "success"), image_size=SIZE, frames=FRAMES)
    out = tmp_path / "rollouts"
    live = []
    with RolloutMonitor(
        env, detector, out=out, adapter=SIM_ADAPTER, recorder=monitor_recorder(out / "recordings")
    ) as monitored:
        for mode in ("grasp", "success"):
            observation, info = monitored.reset(seed=7, options={"mode": mode})
            assert info["task"] == TASK
            verdicts = []
            while True:
                observation, _, terminated, truncated, info = monitored.step(observation["policy_action"])
                verdicts.append(info["robofailring"])
                if terminated or truncated:
                    break
            assert [v.step for v in verdicts] == list(range(FRAMES))
            live.append((verdicts, info["is_success"]))
    records = json.loads((out / "episodes" / "manifest.json").read_text())["episodes"]
    assert [r["outcome"] for r in records] == [("success" if ok else "failure") for _, ok in live]
    assert live[1][1] is True  # the unperturbed run reaches its goal
    for record, trajectory, (verdicts, _) in zip(
        records, load_dataset(out / "episodes").trajectories(), live, strict=True
    ):
        signals, unread = trajectory.read_signals()
        assert unread == [] and {"joint_positions", "gripper_width", "ee_pose", "action"} <= set(signals)
        trace = detector.run(trajectory)
        assert trace.t_det == record["monitor"]["alarm_frame"] == verdicts[-1].first_alarm
        judged = trace.judged_scores_of(trace.rule)
        for view in trace.scored_views:
            assert np.allclose(judged[view], [v.scores[view] for v in verdicts], atol=1e-5)
        recorded = properties(out / "recordings" / f"{record['episode']}.rrd")
        assert recorded["L"] == FRAMES and recorded["t_det"] == (
            verdicts[-1].first_alarm if verdicts[-1].first_alarm is not None else -1
        )
    replayed = CliRunner().invoke(
        app, ["replay", str(out / "episodes"), "--memory", str(sim_memory), "--out", str(tmp_path / "replay")]
    )
    assert replayed.exit_code == 0, replayed.output
    assert len(list((tmp_path / "replay").glob("*.rrd"))) == 2
