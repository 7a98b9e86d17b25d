"""Watch your own policy's rollouts (docs/rollouts.md): a gymnasium wrapper for one env (`RolloutMonitor`) or a
vector env (`VectorRolloutMonitor`) that puts each step's verdict in `info["robofailring"]`, flags or stops on
an alarm, and keeps every episode for review, with a summary of alarms against the env's own success.

The wrappers need the `gym` extra; the adapters, the episode store and the summary do not (`robofailring.monitor.
adapters`, `.episodes`, `.summary`). `SimEnv` (`robofailring.monitor.sim_env`, the `sim` extra) is the embedded
simulator as a gymnasium env.
"""

from __future__ import annotations

from robofailring.monitor.adapters import (
    Adapter,
    LeRobotAdapter,
    ManiSkillAdapter,
    MappingAdapter,
    Observed,
    RobosuiteAdapter,
)
from robofailring.monitor.episodes import RolloutStore, read_rollouts
from robofailring.monitor.summary import RolloutSummary, summarize, write_summary
from robofailring.monitor.tracker import EpisodeRecorder
from robofailring.monitor.vector import VectorRolloutMonitor
from robofailring.monitor.verdict import INFO_KEY, NearestFailure, Verdict
from robofailring.monitor.wrapper import LegacyEnv, RolloutMonitor

__all__ = [
    "INFO_KEY",
    "Adapter",
    "EpisodeRecorder",
    "LeRobotAdapter",
    "LegacyEnv",
    "ManiSkillAdapter",
    "MappingAdapter",
    "NearestFailure",
    "Observed",
    "RobosuiteAdapter",
    "RolloutMonitor",
    "RolloutStore",
    "RolloutSummary",
    "VectorRolloutMonitor",
    "Verdict",
    "read_rollouts",
    "summarize",
    "write_summary",
]
