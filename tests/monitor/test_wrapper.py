"""The rollout monitor on one env (issue 52, items 1-4): each step's verdict in `info`, flag, truncate or a
callable at the alarm, every episode kept in the project layout and read back by the project's own loader,
the alarms equal to `detect` on the saved episodes frame for frame, and bad input named, never scored."""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rollout_env import ADAPTER_SIGNALS, LENGTH, TASK, TEST_RUNS, ReplayEnv
from synthetic import VIEWS

from robofailring import (
    FailureDetector,
    MappingAdapter,
    RolloutError,
    RolloutMonitor,
    Verdict,
    ground,
    load_dataset,
)
from robofailring.errors import BlindCameraWarning, OutputError, SettingError

ADAPTER = MappingAdapter(
    views={view: f"observation.images.{view}" for view in VIEWS}, signals=ADAPTER_SIGNALS
)


def _episode(env: RolloutMonitor) -> list[Verdict]:
    """One episode with the run's own commanded actions; the verdict of every step."""
    env.reset()
    verdicts, done = [], False
    while not done:
        _, _, terminated, truncated, info = env.step(env.unwrapped.expert_action())
        verdicts.append(info["robofailring"])
        done = terminated or truncated
    return verdicts


def test_every_step_has_its_verdict_and_the_failures_fire(detector: FailureDetector, tmp_path: Path) -> None:
    env = RolloutMonitor(ReplayEnv(TEST_RUNS), detector, out=tmp_path / "out", adapter=ADAPTER)
    for symbol, _ in TEST_RUNS:
        verdicts = _episode(env)
        assert [v.step for v in verdicts] == list(range(LENGTH))
        assert all(set(v.scores) == {*VIEWS, "signals"} and v.threshold == 0.05 for v in verdicts)
        assert all(v.task == TASK and v.rule == "contrast" for v in verdicts)
        alarms = [v.step for v in verdicts if v.alarm]
        if symbol is None:
            assert alarms == [] and all(v.nearest is None and v.first_alarm is None for v in verdicts)
            continue
        assert alarms and verdicts[-1].first_alarm == alarms[0]
        first = verdicts[alarms[0]]
        assert max(first.scores[view] for view in first.fired_views) >= first.threshold
        assert first.nearest is not None and first.nearest.task == TASK
        assert first.nearest.symbol in ("grasp_wp2", "slip_wp3")
        assert first.nearest.cause == ground(
            first.nearest.symbol
        )  # the grounded sentence of the nearest failure
        assert all(v.nearest is None for v in verdicts if not v.alarm)
    env.close()


def test_an_uncalibrated_memory_is_said_once_and_in_the_rollout_summary(
    monitor_memory_dir: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """N9: at the default γ = 0 every success alarmed and nothing said why (detect warns, the monitor did not)."""
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING, logger="robofailring"):
        env = RolloutMonitor(ReplayEnv(TEST_RUNS[:2]), monitor_memory_dir, out=out, adapter=ADAPTER)
        _episode(env)
        _episode(env)
        env.close()
    said = [r.getMessage() for r in caplog.records if "judges at its default" in r.getMessage()]
    assert said == [
        "warning: the contrast rule judges at its default γ = 0: the memory is not calibrated for it, so no "
        "false-alarm rate is promised (run `robofailring calibrate SUCCESS_DATA --memory MEMORY`, or give "
        "--gamma)"
    ]
    summary = json.loads((out / "rollouts.json").read_text())
    assert summary["uncalibrated_rules"] == [said[0].removeprefix("warning: ")]
    assert (
        "**Uncalibrated:** the contrast rule judges at its default γ = 0" in (out / "rollouts.md").read_text()
    )


def test_a_calibrated_or_given_threshold_has_no_uncalibrated_note(
    detector: FailureDetector, tmp_path: Path
) -> None:
    env = RolloutMonitor(ReplayEnv(TEST_RUNS[:1]), detector, out=tmp_path / "out", adapter=ADAPTER)
    _episode(env)
    env.close()
    summary = json.loads((tmp_path / "out" / "rollouts.json").read_text())
    assert summary["uncalibrated_rules"] == []
    assert "Uncalibrated" not in (tmp_path / "out" / "rollouts.md").read_text()


def test_the_saved_episodes_read_back_and_detect_fires_where_the_monitor_did(
    detector: FailureDetector, tmp_path: Path
) -> None:
    """Parity: `detect` on each saved episode gives the monitor's alarms and scores, frame for frame."""
    with RolloutMonitor(ReplayEnv(TEST_RUNS), detector, out=tmp_path / "out", adapter=ADAPTER) as env:
        live = [_episode(env) for _ in TEST_RUNS]
    dataset = load_dataset(tmp_path / "out" / "episodes")
    assert dataset.skipped == [] and len(list(dataset.trajectories())) == len(TEST_RUNS)
    for (symbol, _), verdicts, trajectory in zip(TEST_RUNS, live, dataset.trajectories(), strict=True):
        assert trajectory.outcome.value == ("success" if symbol is None else "failure")
        assert trajectory.length == LENGTH and list(trajectory.views) == list(VIEWS)
        assert trajectory.skipped == ()
        signals, unread = trajectory.read_signals()
        assert (
            unread == []
            and set(signals) == {"gripper_width", "action"}
            and signals["action"].values.shape == (LENGTH, 2)
        )
        trace = detector.run(trajectory)
        judged = trace.judged_scores_of(trace.rule)
        assert trace.t_det == verdicts[-1].first_alarm
        for view in (*VIEWS, "signals"):
            assert np.allclose(judged[view], [v.scores[view] for v in verdicts], atol=1e-5), view
        fused = np.nanmax(np.stack([judged[view] for view in (*VIEWS, "signals")]), axis=0)
        assert list(fused >= trace.threshold) == [v.alarm for v in verdicts]
    summary = json.loads((tmp_path / "out" / "rollouts.json").read_text())
    assert summary["confusion"] == {"tp": 4, "fn": 0, "fp": 0, "tn": 2} and summary["recall"] == 1.0
    assert summary["false_alarm_rate"] == 0.0 and summary["unknown_outcome"] == {"episodes": 0, "alarms": 0}
    assert [row["alarm_frame"] for row in summary["rows"]] == [v[-1].first_alarm for v in live]


def test_truncate_stops_the_episode_before_the_alarm_s_action(
    detector: FailureDetector, tmp_path: Path
) -> None:
    inner = ReplayEnv([("grasp_wp2", 1), (None, 1)])
    env = RolloutMonitor(inner, detector, out=tmp_path / "out", adapter=ADAPTER, on_alarm="truncate")
    verdicts = _episode(env)
    stop = verdicts[-1]
    assert stop.alarm and stop.first_alarm == stop.step == len(verdicts) - 1
    assert stop.stopped is not None and stop.stopped.startswith(
        f"alarm at step {stop.step}: contrast score of "
    )
    assert inner.t == stop.step  # the alarm's action was never executed: the env is still at that frame
    with pytest.raises(RolloutError, match="step called before reset"):
        env.step(inner.expert_action())
    assert not any(v.alarm for v in _episode(env))  # the success runs to its end
    env.close()
    records = json.loads((tmp_path / "out" / "episodes" / "manifest.json").read_text())["episodes"]
    assert [(r["frames"], r["outcome"], r["monitor"]["ended"]) for r in records] == [
        (stop.step + 1, None, "alarm"),
        (LENGTH, "success", "terminated"),
    ]
    summary = json.loads((tmp_path / "out" / "rollouts.json").read_text())
    assert summary["unknown_outcome"] == {"episodes": 1, "alarms": 1} and summary["confusion"]["tn"] == 1


def test_a_callable_on_alarm_is_called_at_each_episode_s_first_alarm(detector: FailureDetector) -> None:
    called: list[tuple[str, int]] = []
    env = RolloutMonitor(
        ReplayEnv(TEST_RUNS), detector, adapter=ADAPTER, on_alarm=lambda v: called.append((v.episode, v.step))
    )
    firsts = [_episode(env)[-1].first_alarm for _ in TEST_RUNS]
    assert called == [(TASK, first) for first in firsts if first is not None] and len(called) == 4


def test_bad_settings_and_a_step_before_reset_are_named(detector: FailureDetector, tmp_path: Path) -> None:
    with pytest.raises(SettingError, match="on_alarm must be"):
        RolloutMonitor(ReplayEnv(TEST_RUNS), detector, on_alarm="stop")
    with pytest.raises(SettingError, match="unknown adapter 'ros'"):
        RolloutMonitor(ReplayEnv(TEST_RUNS), detector, adapter="ros")
    env = RolloutMonitor(ReplayEnv(TEST_RUNS), detector, adapter=ADAPTER)
    with pytest.raises(RolloutError, match="step called before reset"):
        env.step(np.zeros(2))
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "episodes").mkdir()
    (tmp_path / "mine" / "episodes" / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match=r"holds notes\.txt"):
        RolloutMonitor(ReplayEnv(TEST_RUNS), detector, out=tmp_path / "mine")
    untasked = ReplayEnv(TEST_RUNS)
    del untasked.task
    with pytest.raises(SettingError, match="the env names no task"):
        RolloutMonitor(untasked, detector, adapter=ADAPTER).reset()


class FaultyEnv(ReplayEnv):
    """The replay env with one fault from step `at` on: a camera gone, an image resized, the state NaN."""

    def __init__(self, fault: str, at: int = 3) -> None:
        super().__init__([("grasp_wp2", 1)])
        self.fault, self.at = fault, at

    def observation(self) -> dict[str, np.ndarray]:
        observation = super().observation()
        if self.t >= self.at:
            if self.fault == "camera":
                del observation["observation.images.wrist"]
            elif self.fault == "size":
                observation["observation.images.front"] = observation["observation.images.front"][:40]
            elif self.fault == "nan":
                observation["observation.state"] = np.full(1, np.nan)
            elif self.fault == "dark":
                observation["observation.images.front"] = np.zeros_like(
                    observation["observation.images.front"]
                )
        return observation


@pytest.mark.parametrize(
    ("fault", "message"),
    [
        ("camera", "step 3: the observation has no 'observation.images.wrist'"),
        ("size", "step 3: view 'front' is 48×40, but the episode began at 48×48"),
    ],
)
def test_a_camera_lost_or_resized_mid_episode_is_a_named_error(
    detector: FailureDetector, fault: str, message: str
) -> None:
    env = RolloutMonitor(FaultyEnv(fault), detector, adapter=ADAPTER)
    env.reset()
    for _ in range(2):
        env.step(env.unwrapped.expert_action())
    with pytest.raises(RolloutError, match=message):
        env.step(env.unwrapped.expert_action())


def test_nan_state_turns_the_signals_off_by_name_for_the_rest_of_the_episode(
    detector: FailureDetector, tmp_path: Path
) -> None:
    with RolloutMonitor(FaultyEnv("nan"), detector, out=tmp_path / "out", adapter=ADAPTER) as env:
        verdicts = _episode(env)
    assert all("signals" in v.scores and v.skipped == () for v in verdicts[:3])
    note = "signals: 'gripper_width' is NaN or infinite at step 3; cameras alone from then"
    assert all(set(v.scores) == set(VIEWS) and v.skipped == (note,) for v in verdicts[3:])
    (record,) = json.loads((tmp_path / "out" / "episodes" / "manifest.json").read_text())["episodes"]
    assert record["monitor"]["notes"] == [
        "signal 'gripper_width': 5 frame(s) missing or not finite (the first 3)"
    ]
    (trajectory,) = load_dataset(tmp_path / "out" / "episodes").trajectories()
    assert trajectory.length == LENGTH  # kept whole: NaN rows saved, the loader says so when scoring


def test_a_camera_gone_dark_is_named_in_every_verdict_from_then_on(detector: FailureDetector) -> None:
    """A black camera is never a silent `alarm=False`: the verdict names it (StepResult.blind_views), and a
    step whose every view is still judged stays usable."""
    with pytest.warns(BlindCameraWarning, match="front"):
        verdicts = _episode(RolloutMonitor(FaultyEnv("dark"), detector, adapter=ADAPTER))
    assert all(v.blind_views == () for v in verdicts[:3])
    assert all(v.blind_views == ("front",) and np.isnan(v.scores["front"]) for v in verdicts[3:])
    assert all(v.usable for v in verdicts)  # the other camera and the signals still judge


class InterruptedEnv(ReplayEnv):
    """Ctrl-C in the middle of the second episode."""

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        if self.episode == 1 and self.t == 4:
            raise KeyboardInterrupt
        return super().step(action)


def test_an_interrupted_run_keeps_every_episode_readable(detector: FailureDetector, tmp_path: Path) -> None:
    with (
        pytest.raises(KeyboardInterrupt),
        RolloutMonitor(InterruptedEnv(TEST_RUNS), detector, out=tmp_path / "out", adapter=ADAPTER) as env,
    ):
        for _ in TEST_RUNS:
            _episode(env)
    trajectories = load_dataset(tmp_path / "out" / "episodes").trajectories()
    assert [t.length for t in trajectories] == [LENGTH, 5]  # the second kept as far as it was judged
    records = json.loads((tmp_path / "out" / "episodes" / "manifest.json").read_text())["episodes"]
    assert [r["monitor"]["ended"] for r in records] == ["terminated", "closed"]
    assert [r["outcome"] for r in records] == ["failure", None]
    # the folder takes more rollouts, numbered on
    with RolloutMonitor(ReplayEnv(TEST_RUNS), detector, out=tmp_path / "out", adapter=ADAPTER) as env:
        _episode(env)
    assert [t.episode for t in load_dataset(tmp_path / "out" / "episodes").trajectories()] == [
        "episode_00000",
        "episode_00001",
        "episode_00002",
    ]


def test_the_monitor_installs_beside_lerobot_s_rerun_it_loads_none() -> None:
    """LeRobot pins an older rerun-sdk: the monitor (the gym extra) imports no Rerun, torch or simulator."""
    import subprocess
    import sys

    probe = (
        "import json, sys; import robofailring.monitor; "
        "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules} & {'rerun', 'torch', 'pybullet', 'rfr_viz'})))"
    )
    loaded = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True).stdout
    assert json.loads(loaded) == []
