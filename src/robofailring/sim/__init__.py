"""The embedded default dataset: a small PyBullet FailGen (Panda, tabletop tasks, three cameras)."""

from __future__ import annotations

from robofailring.sim.cameras import VIEWS
from robofailring.sim.episode import DURATION_S, EpisodeResult, EpisodeRun, run_episode
from robofailring.sim.job import (
    GenerateConfig,
    describe_dataset,
    episode_dir_name,
    episode_seed,
    generate_dataset,
    simulate,
)
from robofailring.sim.perturb import FAILURE_FAMILIES, FAILURE_MODES, KINDS, SUCCESS, Perturbation
from robofailring.sim.sheet import contact_sheet
from robofailring.sim.tasks import TASKS, GoalCheck

__all__ = [
    "DURATION_S",
    "FAILURE_FAMILIES",
    "FAILURE_MODES",
    "KINDS",
    "SUCCESS",
    "TASKS",
    "VIEWS",
    "EpisodeResult",
    "EpisodeRun",
    "GenerateConfig",
    "GoalCheck",
    "Perturbation",
    "contact_sheet",
    "describe_dataset",
    "episode_dir_name",
    "episode_seed",
    "generate_dataset",
    "run_episode",
    "simulate",
]
