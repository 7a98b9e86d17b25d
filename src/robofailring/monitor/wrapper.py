"""`RolloutMonitor`: a `gymnasium.Wrapper` that judges every step of one env, says so in `info`, flags or stops
on an alarm, and keeps every episode for review (docs/rollouts.md). `LegacyEnv` puts robosuite's and LIBERO's
old API (`reset() -> obs`, `step -> (obs, reward, done, info)`) behind gymnasium's."""

from __future__ import annotations

from pathlib import Path
from typing import Any, SupportsFloat

from robofailring.detection.detector import FailureDetector
from robofailring.extras import needs_extra
from robofailring.monitor.adapters import Adapter
from robofailring.monitor.episodes import EpisodeEnd
from robofailring.monitor.tracker import (
    FLAG,
    TRUNCATE,
    EpisodeRecorder,
    OnAlarm,
    Tracker,
    monitor_core,
    task_of,
)
from robofailring.monitor.verdict import INFO_KEY

with needs_extra("gym"):
    import gymnasium as gym


class LegacyEnv(gym.Env[Any, Any]):
    """An env of the old API (robosuite, LIBERO, robomimic's) as a gymnasium env: `done` is `terminated`; at
    the end, the env's own `check_success()` (LIBERO) or `_check_success()` (robosuite) is `info["is_success"]`.
    Other attributes (LIBERO's `language_instruction`) are the wrapped env's."""

    def __init__(self, env: Any) -> None:
        self.legacy = env

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_") or name == "legacy":
            raise AttributeError(name)
        return getattr(self.legacy, name)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        if seed is not None and hasattr(self.legacy, "seed"):
            self.legacy.seed(seed)
        return self.legacy.reset(), {}

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        result = self.legacy.step(action)
        if len(result) == 5:
            return tuple(result)
        observation, reward, done, info = result
        info = dict(info or {})
        if done and not any(key in info for key in ("is_success", "success")):
            check = getattr(self.legacy, "check_success", None) or getattr(
                self.legacy, "_check_success", None
            )
            if check is not None:
                info["is_success"] = bool(check())
        return observation, reward, bool(done), False, info

    def close(self) -> None:
        if hasattr(self.legacy, "close"):
            self.legacy.close()


class RolloutMonitor(gym.Wrapper[Any, Any, Any, Any]):
    """Watch one env's rollouts with a failure memory: each step's verdict in `info["robofailring"]` (a
    `Verdict`), and every episode kept under `out` (`<out>/episodes`, a dataset `replay`, `review`, `triage` and
    `evaluate` read; `<out>/rollouts.json` and `.md`, the summary).

    `memory` is a memory folder or a `FailureDetector`; `adapter` reads the observations (`auto`: by their keys;
    `lerobot`, `maniskill`, `robosuite`, or an `Adapter` such as `MappingAdapter`); `task` is the memory's
    task, else the env's own (`task`, `task_description`, `language_instruction`). `on_alarm`: `flag` (the
    verdict says so), `truncate` (the step's action is not executed: the step returns the observation it was
    judged on with `truncated=True` and the reason in the verdict's `stopped`), or a callable, called with the
    verdict at each episode's first alarm. `recorder` opens a live recording per episode
    (`rfr_viz.monitor_recorder`, the `viz` extra). An env of the old 4-tuple API is put in a `LegacyEnv`.
    """

    def __init__(
        self,
        env: Any,
        memory: FailureDetector | str | Path,
        *,
        out: str | Path | None = None,
        adapter: str | Adapter | None = "auto",
        task: str | None = None,
        on_alarm: OnAlarm = FLAG,
        recorder: EpisodeRecorder | None = None,
        fps: float | None = None,
    ) -> None:
        super().__init__(env if isinstance(env, gym.Env) else LegacyEnv(env))
        self.core = monitor_core(
            memory,
            out=out,
            adapter=adapter,
            task=task,
            on_alarm=on_alarm,
            recorder=recorder,
            fps=fps,
        )
        self.tracker = Tracker(self.core)
        self._observation: Any = None

    @property
    def detector(self) -> FailureDetector:
        return self.core.detector

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        observation, info = self.env.reset(seed=seed, options=options)
        task = self.core.task or task_of(info, self.env.get_wrapper_attr, self.detector.memory.tasks)
        self.tracker.begin(observation, task)
        self._observation = observation
        return observation, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        verdict = self.tracker.judge(action)
        if verdict.alarm and self.core.on_alarm == TRUNCATE:
            verdict = self.tracker.cut(verdict, executed=False)
            return self._observation, 0.0, False, True, {INFO_KEY: verdict}
        observation, reward, terminated, truncated, info = self.env.step(action)
        info = {**info, INFO_KEY: verdict}
        if terminated or truncated:
            self.tracker.finish(info, terminated=terminated)
        else:
            self.tracker.observe(observation)
            self._observation = observation
        return observation, reward, terminated, truncated, info

    def close(self) -> None:
        """Keep the episode still running (ended `closed`, outcome unknown), release the folder, close the env."""
        try:
            self.tracker.end(EpisodeEnd(outcome=None, reason="closed"))
        finally:
            self.core.close()
            super().close()
