"""The monitor without gymnasium: one `Tracker` per stream of episodes (the env, or each sub-env of a vector
env), all sharing one `MonitorCore` (the detector, the adapter, what to do at an alarm, where episodes go).

A step's verdict judges the (observation, action) pair the step executes: the observation the loop saw (the
reset's, or the last step's) with the action the policy chose for it, as a LeRobot dataset pairs them. Each
is fed to the live step API (`FailureDetector.session(task).step(images, signals=…)`); nothing here scores.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Mapping, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Final, Protocol

import numpy as np

from robofailring.detection.detector import FailureDetector
from robofailring.detection.session import DetectorSession, StepSink
from robofailring.errors import RolloutError, SettingError
from robofailring.monitor.adapters import Adapter, Observed, adapter_for, named_adapter, outcome_of
from robofailring.monitor.episodes import EpisodeDraft, EpisodeEnd, RolloutStore
from robofailring.monitor.summary import summarize, write_summary
from robofailring.monitor.verdict import Verdict, verdict_of

_log = logging.getLogger("robofailring")
FLAG: Final[str] = "flag"  # on_alarm: the verdict says so, the episode goes on
TRUNCATE: Final[str] = "truncate"  # on_alarm: the episode is cut (truncated, never terminated)
EPISODES: Final[str] = "episodes"  # <out>/episodes: the saved rollouts, a dataset

OnAlarm = str | Callable[[Verdict], object]  # "flag", "truncate", or called at an episode's first alarm


class EpisodeRecorder(Protocol):
    """Opens a step sink per episode (`rfr_viz.monitor_recorder`: a live `.rrd` each)."""

    def episode(
        self, detector: FailureDetector, *, task: str, views: Sequence[str], name: str
    ) -> AbstractContextManager[StepSink]: ...


@dataclass
class MonitorCore:
    """What every tracker of one monitor shares: built once by `monitor_core`."""

    detector: FailureDetector
    adapter: Adapter | None  # None until the first observation picks one
    task: str | None  # None: each episode's task comes from the env
    on_alarm: OnAlarm
    out: Path | None = None
    store: RolloutStore | None = None
    recorder: EpisodeRecorder | None = None

    def kept(self) -> None:
        """Rewrite the summary after an episode was kept (an interrupted run still has it)."""
        if self.store is not None and self.out is not None:
            write_summary(summarize(self.store.records, uncalibrated=self.detector.uncalibrated), self.out)

    def close(self) -> None:
        if self.store is not None:
            self.store.close()


def monitor_core(
    detector: FailureDetector | str | Path,
    *,
    out: str | Path | None,
    adapter: str | Adapter | None,
    task: str | None,
    on_alarm: OnAlarm,
    recorder: EpisodeRecorder | None,
    fps: float | None,
) -> MonitorCore:
    """The shared part of a monitor: `detector` or the memory folder to open one from; `out` the folder of
    the saved rollouts (`<out>/episodes`) and their summary (`<out>/rollouts.json`, `.md`), None: none kept."""
    if not (on_alarm in (FLAG, TRUNCATE) or callable(on_alarm)):
        raise SettingError(f"on_alarm must be 'flag', 'truncate' or a callable, got {on_alarm!r}")
    if not isinstance(detector, FailureDetector):
        from robofailring.detection.loader import open_detector

        detector = open_detector(detector)
    for note in detector.uncalibrated:  # said once, as `detect` says it: an alarm at γ = 0 promises nothing
        _log.warning("warning: %s", note)
    store = RolloutStore(Path(out) / EPISODES, fps=fps) if out is not None else None
    return MonitorCore(
        detector=detector,
        adapter=named_adapter(adapter),
        task=task,
        on_alarm=on_alarm,
        out=Path(out) if out is not None else None,
        store=store,
        recorder=recorder,
    )


@dataclass
class Tracker:
    """One stream of episodes: its open episode's session, the observation awaiting its action, its draft."""

    core: MonitorCore
    where: str = ""  # "sub-env 2: " in a vector env's messages
    session: DetectorSession | None = None
    pending: Observed | None = None  # the observation the next action is taken from
    draft: EpisodeDraft | None = None
    episode: str = ""
    first_alarm: int | None = None
    signals_off: str | None = None  # why the signals are left out for the rest of the episode
    sizes: dict[str, tuple[int, ...]] = field(default_factory=dict)
    _sink: contextlib.ExitStack = field(default_factory=contextlib.ExitStack)

    @property
    def open(self) -> bool:
        return self.session is not None

    def begin(self, observation: Any, task: str) -> None:
        """A new episode from the reset's `observation`; an episode still open is kept as ended by the reset."""
        if self.open:
            self.end(EpisodeEnd(outcome=None, reason="reset"))
        core = self.core
        adapter = core.adapter if core.adapter is not None else adapter_for(observation)
        core.adapter = adapter
        observed = adapter.observe(observation, step=0)
        self.draft = core.store.draft(task) if core.store is not None else None
        if self.draft is not None:
            self.draft.dims = self._dims(task)
        self.episode = self.draft.name if self.draft is not None else task
        sink = None
        if core.recorder is not None:
            recording = core.recorder.episode(
                core.detector, task=task, views=list(observed.views), name=self.episode
            )
            sink = self._sink.enter_context(recording)
        self.session = core.detector.session(task, sink=sink)
        self.sizes = {view: image.shape for view, image in observed.views.items()}
        self.pending, self.first_alarm, self.signals_off = observed, None, None

    def _dims(self, task: str) -> dict[str, tuple[str, ...]]:
        """The dimension names of the task's signals in the memory, for the saved episode (so that `detect` on it
        selects what the session did)."""
        memory = self.core.detector.memory.signals
        found = memory.task(task) if memory is not None else None
        if found is None:
            return {}
        layout = found.layout
        return {name: tuple(layout.full.get(name, dims)) for name, dims in (*layout.state, *layout.action)}

    def observe(self, observation: Any) -> None:
        """The observation the env returned: judged with the next action."""
        assert self.core.adapter is not None and self.session is not None
        observed = self.core.adapter.observe(observation, step=self.session.t)
        for view, shape in self.sizes.items():
            if view not in observed.views:
                raise RolloutError(
                    f"{self.where}step {self.session.t}: the observation has no view {view!r} (the episode began "
                    f"with {', '.join(self.sizes)}); a camera may not drop out mid-episode"
                )
            if observed.views[view].shape != shape:
                raise RolloutError(
                    f"{self.where}step {self.session.t}: view {view!r} is {_size(observed.views[view].shape)}, "
                    f"but the episode began at {_size(shape)}; an image may not change size mid-episode"
                )
        self.pending = observed

    def judge(self, action: Any) -> Verdict:
        """The verdict on the pending observation with the `action` taken from it."""
        session, observed, adapter = self.session, self.pending, self.core.adapter
        if session is None or observed is None or adapter is None:
            raise RolloutError(
                f"{self.where}step called before reset (or after the episode ended): call reset() first"
            )
        self.pending = None
        signals = observed.signals | adapter.action_signals(action, step=session.t)
        fed, skipped = self._fed(signals, session.t)
        result = session.step(observed.views, signals=fed)
        if result.alarm and self.first_alarm is None:
            self.first_alarm = result.t
        verdict = verdict_of(
            result, episode=self.episode, task=session.task, first_alarm=self.first_alarm, skipped=skipped
        )
        if self.draft is not None:
            kinds = {name: adapter.kind(name) for name in signals}
            self.draft.add(observed.views, signals, kinds, verdict)
        on_alarm = self.core.on_alarm
        if callable(on_alarm) and result.alarm and self.first_alarm == result.t:
            on_alarm(verdict)
        return verdict

    def _fed(
        self, signals: dict[str, np.ndarray], t: int
    ) -> tuple[dict[str, np.ndarray] | None, tuple[str, ...]]:
        """The signals the session is given (None: cameras alone) and what was skipped, by name: a signal the
        task's signal memory uses that is missing or not finite turns them off for the rest of the episode."""
        assert self.session is not None
        memory = self.core.detector.memory.signals
        task = memory.task(self.session.task) if memory is not None else None
        if task is None:
            return None, ()
        if self.signals_off is None:
            for name in task.layout.names:
                if name not in signals:
                    self.signals_off = (
                        f"signals: the memory's {name!r} is not in the observation or action (given: "
                        f"{', '.join(signals) or 'none'}); cameras alone from step {t}"
                    )
                    break
                if not np.isfinite(signals[name]).all():
                    self.signals_off = (
                        f"signals: {name!r} is NaN or infinite at step {t}; cameras alone from then"
                    )
                    break
        if self.signals_off is not None:
            return None, (self.signals_off,)
        return signals, ()

    def finish(self, info: Mapping[str, Any], *, terminated: bool) -> None:
        """The env ended the episode (`terminated`, else truncated): kept with the env's own outcome in `info`."""
        self.end(EpisodeEnd(outcome=outcome_of(info), reason="terminated" if terminated else "truncated"))

    def cut(self, verdict: Verdict, *, executed: bool) -> Verdict:
        """The monitor ends the episode at `verdict`'s alarm (`on_alarm="truncate"`): kept as cut there, and the
        verdict saying why (`stopped`, with whether the alarm's action was `executed`)."""
        stopped = alarm_reason(verdict, executed=executed)
        self.end(EpisodeEnd(outcome=None, reason="alarm", stopped=stopped))
        return replace(verdict, stopped=stopped)

    def end(self, end: EpisodeEnd) -> dict[str, Any] | None:
        """Close the open episode: its recording saved, the episode kept with how it ended (its record)."""
        if not self.open:
            return None
        record = None
        try:
            self._sink.close()
        finally:
            if self.draft is not None and self.core.store is not None:
                assert self.session is not None
                record = self.core.store.keep(self.draft, end, rule=self.session.rule.name)
                self.core.kept()
            self.session, self.pending, self.draft = None, None, None
            self._sink = contextlib.ExitStack()
        return record


def _size(shape: tuple[int, ...]) -> str:
    return f"{shape[1]}×{shape[0]}"


#: Where an env names its task: a key of its reset `info`, else an attribute (LeRobot's `task`, LIBERO's language).
TASK_KEYS: Final[tuple[str, ...]] = ("task", "task_description", "language_instruction")


def task_of(info: dict[str, Any], attribute: Callable[[str], Any], memory_tasks: Sequence[str]) -> str:
    """The episode's task as the env names it: in its reset `info`, else `attribute(name)` of the env."""
    for key in TASK_KEYS:
        if isinstance(info.get(key), str) and info[key]:
            return str(info[key])
    for key in TASK_KEYS:
        try:
            value = attribute(key)
        except AttributeError:
            continue
        if isinstance(value, str) and value:
            return value
    raise SettingError(
        f"the env names no task (no {', '.join(TASK_KEYS)} in its reset info or attributes): pass task=, one of "
        f"the memory's tasks ({', '.join(memory_tasks)})"
    )


def alarm_reason(verdict: Verdict, *, executed: bool) -> str:
    """Why an episode was cut at its alarm, in a sentence for `info` and the summary."""
    view = max(verdict.fired_views, key=lambda name: verdict.scores[name]) if verdict.fired_views else "?"
    return (
        f"alarm at step {verdict.step}: {verdict.rule} score of {view} {verdict.scores.get(view, float('nan')):.3f} "
        f"≥ {verdict.threshold:.3f}; the step's action was {'executed' if executed else 'not executed'}"
    )
