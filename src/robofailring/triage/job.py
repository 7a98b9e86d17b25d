"""The triage job's library part: load the data, choose each task's reference, score every episode
streaming (one at a time; only its small summary is kept), and rank them."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Final

from robofailring.data.labels import Label, label_key, read_labels
from robofailring.data.model import Outcome, Skipped, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_DETECTOR, DetectorConfig
from robofailring.detection.detector import FailureDetector
from robofailring.detection.scored import prefetch_scored
from robofailring.errors import DataError, SettingError
from robofailring.memory.recipe import DEFAULT_RECIPE
from robofailring.progress import progress_bar
from robofailring.triage.ranking import TaskScale, rank
from robofailring.triage.reference import Reference, built_reference, memory_reference
from robofailring.triage.scoring import EpisodeScore, score_episode
from robofailring.triage.table import check_unique_episodes

DEFAULT_REFERENCE_RUNS: Final[int] = 100
# episodes whose frames an encoder working ahead (`--ray`) is handed at once: one Ray pass each, and only
# their frame references held, so memory stays flat in the number of episodes
PREFETCH_EPISODES: Final[int] = 64


@dataclass(frozen=True)
class TriageConfig:
    """What `robofailring triage` ranks and how: `detector` holds the memory to judge by (its rules as
    calibrated, its own encoder), or without one the encoder the reference is built with (default: the
    recipe's), and the detector's rule, data root, scoring (K) and placement (device, runtime, cache, Ray)."""

    # the dataset to triage (any layout; outcomes its layout states are not used), how it is read: the
    # success rows of its labels are known-good runs
    data: DataSelection
    out: Path  # folder for triage.csv, triage.rrd, triage.html and the replays
    detector: DetectorConfig = DEFAULT_DETECTOR
    known_good: Path | None = None  # a dataset of known-good runs (every episode a success), read as `data`
    reference_runs: int = DEFAULT_REFERENCE_RUNS  # per task, at most this many other episodes as reference

    def __post_init__(self) -> None:  # bad settings fail before any frame is encoded
        if self.detector.memory is not None and self.known_good is not None:
            raise SettingError(
                "--memory and --successes go separately: add the known-good runs to the memory first "
                "(build-memory SUCCESSES --add-to MEMORY), then triage with --memory"
            )
        if self.reference_runs < 2:
            raise SettingError(f"--reference-runs must be at least 2, got {self.reference_runs}")

    @property
    def memory(self) -> Path | None:
        """The memory to judge by (None: a reference built from the data)."""
        return self.detector.memory

    @property
    def encoder(self) -> str:
        """The encoder a reference built from the data uses (a memory uses its own)."""
        return self.detector.encoder or DEFAULT_RECIPE.encoder


@dataclass
class TriageResult:
    """The ranked episodes, the detector that scored them, and what was not read or not scored."""

    ranked: list[EpisodeScore]
    detector: FailureDetector
    modes: dict[str, str]  # per task: the reference it was judged against
    trajectories: dict[str, Trajectory]  # by key, frames read on demand (for replays and thumbnails)
    notes: list[str] = field(default_factory=list)
    skipped_inputs: list[Skipped] = field(default_factory=list)


def load_episodes(config: TriageConfig) -> tuple[list[Trajectory], list[Skipped]]:
    """The data's episodes as unlabelled runs, with `config.data.labels` applied as every verb applies them
    (outcome, symbol, and the task column, which a folder of several tasks needs); outcomes the data's
    own names state are dropped."""
    dataset = config.data.load()
    labels = (
        read_labels(config.data.labels, vocabulary=config.data.read_vocabulary())
        if config.data.labels is not None
        else {}
    )
    found = [
        t if _labelled(t, labels) else replace(t, outcome=None, symbol=None, description=None)
        for t in dataset.trajectories()
    ]
    check_unique_episodes(found)
    return found, list(dataset.skipped)


def _labelled(trajectory: Trajectory, labels: dict[str, Label]) -> bool:
    """Whether a labels row gives `trajectory` an outcome (a row of its task alone leaves it unlabelled)."""
    key = label_key(trajectory, labels)
    return key is not None and labels[key].outcome is not None


def run_triage(config: TriageConfig) -> TriageResult:
    """Score and rank every episode of `config.data` (docs/triage.md)."""
    trajectories, skipped = load_episodes(config)
    _require_two_frames(trajectories, config.data.root)
    tasks = list(dict.fromkeys(t.task for t in trajectories))
    reference = _reference(config, trajectories, tasks, skipped)
    scores: list[EpisodeScore] = []
    with progress_bar(total=len(trajectories), desc="triage", unit="episode") as bar:
        for start in range(0, len(trajectories), PREFETCH_EPISODES):
            chunk = trajectories[start : start + PREFETCH_EPISODES]
            prefetch_scored(reference.detector.encoder, chunk)
            for trajectory in chunk:
                scores.append(
                    score_episode(reference.detector, trajectory, mode=reference.modes[trajectory.task])
                )
                bar.update(1)
    scales = _scales(reference, scores, trajectories)
    ranked = rank(scores, scales)
    notes = list(reference.notes)
    for score in ranked:
        skipped += score.skipped
    return TriageResult(
        ranked=ranked,
        detector=reference.detector,
        modes=reference.modes,
        trajectories={t.key: t for t in trajectories},
        notes=notes,
        skipped_inputs=skipped,
    )


def _require_two_frames(trajectories: list[Trajectory], data: Path) -> None:
    """DataError when no episode has a view of 2 frames: each frame is scored against its run's first, so
    such data has nothing to rank (said before a reference is built, which would blame it instead)."""
    if not trajectories or any(len(frames) >= 2 for t in trajectories for frames in t.views.values()):
        return
    example = trajectories[0]
    raise DataError(
        f"none of the {len(trajectories)} episode(s) of {data} has a view of at least 2 frames (e.g. "
        f"{example.key}: {example.length} frame(s)); triage scores each frame against its run's first "
        "frame, so a run needs 2 frames at least"
    )


def _reference(
    config: TriageConfig, trajectories: list[Trajectory], tasks: list[str], skipped: list[Skipped]
) -> Reference:
    if config.memory is not None:
        return memory_reference(config.detector, tasks, data=config.data.root)
    known_good: list[Trajectory] = []
    if config.known_good is not None:
        good = replace(config.data, root=config.known_good, labels=None).load()
        skipped += good.skipped
        known_good = [replace(t, outcome=Outcome.SUCCESS, symbol=None) for t in good if t.task in tasks]
    return built_reference(
        trajectories,
        known_good,
        config.detector.placement.open(config.encoder),
        data=config.data.root,
        encoder_spec=config.encoder,
        detector=config.detector,
        reference_runs=config.reference_runs,
    )


def _scales(
    reference: Reference, scores: list[EpisodeScore], trajectories: list[Trajectory]
) -> dict[str, TaskScale | None]:
    """Per task: the scale of the peaks of its episodes not labelled failure and of its known-good runs
    from elsewhere (`--successes`, each scored leaving itself out)."""
    failed = {t.key for t in trajectories if t.outcome is Outcome.FAILURE}
    by_key = {score.key: score for score in scores}
    peaks: dict[str, list[float]] = {}
    for score in scores:
        if score.key not in failed:
            peaks.setdefault(score.task, []).append(score.peak)
    for task, runs in reference.runs.items():
        for run in runs:
            if run.key not in by_key:
                peaks.setdefault(task, []).append(score_episode(reference.detector, run, mode="").peak)
    return {task: TaskScale.of(found) for task, found in peaks.items()}
