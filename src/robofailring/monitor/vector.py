"""`VectorRolloutMonitor`: the monitor around a gymnasium vector env, one session per sub-env.

A sub-env that ends while the others run is kept as its own episode and begun again from its reset, in
whichever autoreset mode the env has (gymnasium's `metadata["autoreset_mode"]`): `next-step` (the step after the
end resets it; its action is ignored, so nothing is judged), `same-step` (the end's observation is already the
next episode's first), `disabled` (the loop resets it with `reset(options={"reset_mask": …})`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from robofailring.detection.detector import FailureDetector
from robofailring.errors import SettingError
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
from robofailring.monitor.verdict import INFO_KEY, Verdict

with needs_extra("gym"):
    from gymnasium.vector import AutoresetMode, VectorEnv, VectorWrapper


def sub_value(value: Any, index: int) -> Any:
    """Sub-env `index`'s part of a batched observation or action (nested mappings, arrays, tensors)."""
    if isinstance(value, Mapping):
        return {key: sub_value(item, index) for key, item in value.items()}
    return value[index]


def sub_info(info: Mapping[str, Any], index: int) -> dict[str, Any]:
    """Sub-env `index`'s part of a vector env's `info` (each key's array where its `_key` mask says so)."""
    found = {}
    for key, value in info.items():
        if key.startswith("_"):
            continue
        mask = info.get(f"_{key}")
        if mask is not None and not bool(mask[index]):
            continue
        found[key] = sub_info(value, index) if isinstance(value, Mapping) else value[index]
    return found


class VectorRolloutMonitor(VectorWrapper):
    """`RolloutMonitor` for a vector env: `info["robofailring"]` is an object array of each sub-env's `Verdict`
    (None where a sub-env was reset at this step), `info["_robofailring"]` its mask. `on_alarm="truncate"` needs
    the `disabled` autoreset mode (a vector env steps every sub-env: the alarm's action is executed, then the
    sub-env is reported truncated and the loop resets it)."""

    def __init__(
        self,
        env: VectorEnv,
        memory: FailureDetector | str | Path,
        *,
        out: str | Path | None = None,
        adapter: str | Adapter | None = "auto",
        task: str | None = None,
        on_alarm: OnAlarm = FLAG,
        recorder: EpisodeRecorder | None = None,
        fps: float | None = None,
    ) -> None:
        super().__init__(env)
        self.mode = AutoresetMode(env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP))
        if on_alarm == TRUNCATE and self.mode is not AutoresetMode.DISABLED:
            raise SettingError(
                f"on_alarm='truncate' on a vector env needs autoreset_mode=Disabled (this one's is "
                f"{self.mode.value}): only then does the loop reset a sub-env the monitor cut"
            )
        self.core = monitor_core(
            memory,
            out=out,
            adapter=adapter,
            task=task,
            on_alarm=on_alarm,
            recorder=recorder,
            fps=fps,
        )
        self.trackers = [Tracker(self.core, where=f"sub-env {index}: ") for index in range(self.num_envs)]
        self._resetting = np.zeros(self.num_envs, bool)  # next-step mode: this step resets these

    def _task(self, info: Mapping[str, Any], index: int) -> str:
        if self.core.task is not None:
            return self.core.task

        def attribute(name: str) -> Any:
            return self.env.get_attr(name)[index]  # type: ignore[attr-defined]  # SyncVectorEnv's, AsyncVectorEnv's

        return task_of(sub_info(info, index), attribute, self.core.detector.memory.tasks)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        mask = None if options is None else options.get("reset_mask")  # the env pops it from its options
        observations, info = self.env.reset(seed=seed, options=None if options is None else dict(options))
        for index, tracker in enumerate(self.trackers):
            if mask is None or bool(mask[index]):
                tracker.begin(sub_value(observations, index), self._task(info, index))
                self._resetting[index] = False
        return observations, info

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        verdicts: list[Verdict | None] = [None] * self.num_envs
        for index, tracker in enumerate(self.trackers):
            if not self._resetting[index]:
                verdicts[index] = tracker.judge(sub_value(actions, index))
        observations, rewards, terminations, truncations, info = self.env.step(actions)
        truncations = np.array(truncations, copy=True)
        for index, tracker in enumerate(self.trackers):
            verdict = verdicts[index]
            if self._resetting[index]:  # this step reset it: its observation begins the next episode
                self._resetting[index] = False
                tracker.begin(sub_value(observations, index), self._task(info, index))
            elif bool(terminations[index]) or bool(truncations[index]):
                tracker.finish(sub_info(info, index), terminated=bool(terminations[index]))
                if self.mode is AutoresetMode.SAME_STEP:
                    tracker.begin(sub_value(observations, index), self._task(info, index))
                elif self.mode is AutoresetMode.NEXT_STEP:
                    self._resetting[index] = True
            elif verdict is not None and verdict.alarm and self.core.on_alarm == TRUNCATE:
                verdicts[index] = tracker.cut(verdict, executed=True)
                truncations[index] = True
            else:
                tracker.observe(sub_value(observations, index))
        judged = np.empty(self.num_envs, dtype=object)
        judged[:] = verdicts
        info = {**info, INFO_KEY: judged, f"_{INFO_KEY}": np.array([v is not None for v in verdicts])}
        return observations, rewards, terminations, truncations, info

    def close(self, **kwargs: Any) -> None:
        """Keep every sub-env's running episode (ended `closed`), release the folder, close the env."""
        try:
            for tracker in self.trackers:
                tracker.end(EpisodeEnd(outcome=None, reason="closed"))
        finally:
            self.core.close()
            super().close(**kwargs)
