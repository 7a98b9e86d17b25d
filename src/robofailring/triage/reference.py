"""What each task's episodes are judged against: a memory, known-good runs, or the task's other episodes.

Three references, chosen per task (docs/triage.md):

- `memory`: a memory folder, with its rules and thresholds as calibrated (novelty where it holds
  success runs only); every task of the data must be one of the memory's.
- `successes`: the task's known-good runs (`--successes`, or the rows of `--labels` marked success)
  form a success memory, judged by the novelty rule (N = 1 − S⁺); runs labelled failure join a
  failure memory beside it, which names the nearest failure at each peak (`--score contrast` also
  scores by it, at the cost of ranking failures of types it lacks low).
- `others`: a task without a known-good run is scored against its own other episodes, each leaving
  itself out (at most `reference_runs` of them, a fixed sample): a minority of failures stands
  out, which assumes that most runs of the task succeeded.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Final

from robofailring.data.model import Outcome, Trajectory
from robofailring.detection.config import DetectorConfig
from robofailring.detection.detector import FailureDetector
from robofailring.detection.loader import detector_from, detector_with
from robofailring.detection.rules import NOVELTY
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import DataError
from robofailring.memory.builder import Provenance, build_memories

MEMORY: Final[str] = "memory"
SUCCESSES: Final[str] = "successes"
OTHERS: Final[str] = "others"
OTHERS_NOTE: Final[str] = (
    "no known-good run of task {task!r}: each of its episodes is scored against its other {count} "
    "episode(s), leaving itself out; this assumes most runs of the task succeeded"
)


@dataclass(frozen=True)
class Reference:
    """The detector every episode is scored by, and per task which reference it holds."""

    detector: FailureDetector
    modes: dict[str, str]  # per task: MEMORY, SUCCESSES or OTHERS
    # per task: its reference runs (known-good runs, or a sample of its other episodes); none with a memory
    runs: dict[str, list[Trajectory]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def memory_reference(config: DetectorConfig, tasks: Sequence[str], *, data: Path) -> Reference:
    """The detector on `config.memory` (its rules and thresholds as stored, or `config.rule`); a task it
    does not know is an error. `config.placement.ray`: where the frames are encoded ahead (docs/ray.md); `data`: the
    data triaged, where the memory's images may be read from (`FailureMemory.image_roots`)."""
    memory_dir = config.memory_dir
    detector = detector_from(config, trusted=[data])
    unknown = sorted(set(tasks) - set(detector.memory.tasks))
    if unknown:
        raise DataError(
            f"task(s) {', '.join(map(repr, unknown))} of the data have no run in memory {memory_dir} "
            f"(its tasks: {', '.join(detector.memory.tasks)}); leave --memory out to score them against "
            "known-good runs (--successes, --labels) or against their other episodes"
        )
    return Reference(
        detector=detector, modes={task: MEMORY for task in tasks}, notes=list(detector.uncalibrated)
    )


def built_reference(
    trajectories: Sequence[Trajectory],
    known_good: Sequence[Trajectory],
    encoder: CachedEncoder,
    *,
    data: Path,
    encoder_spec: str,
    detector: DetectorConfig,
    reference_runs: int,
) -> Reference:
    """A memory built here: per task, its known-good runs (else its other episodes) as success runs, and
    every run labelled failure as a failure entry.

    `trajectories` are the data's episodes with the outcomes `--labels` gives (None: unlabelled);
    `known_good` the runs of `--successes`. `detector`: its K and rule (default novelty).
    """
    tasks = list(dict.fromkeys(t.task for t in trajectories))
    failures = [t for t in trajectories if t.outcome is Outcome.FAILURE]
    modes: dict[str, str] = {}
    runs: dict[str, list[Trajectory]] = {}
    notes: list[str] = []
    for task in tasks:
        good = [t for t in (*trajectories, *known_good) if t.task == task and t.outcome is Outcome.SUCCESS]
        if good:
            modes[task], runs[task] = SUCCESSES, good
            continue
        others = [t for t in trajectories if t.task == task and t.outcome is None]
        if not others:
            raise DataError(
                f"every episode of task {task!r} is labelled failure and no known-good run of it is given: "
                "nothing normal to compare them with; pass --successes DATA (runs that went well)"
            )
        modes[task], runs[task] = OTHERS, _sample(others, reference_runs)
        notes.append(OTHERS_NOTE.format(task=task, count=max(len(runs[task]) - 1, 0)))
    success_runs = [replace(t, outcome=Outcome.SUCCESS, symbol=None) for task in tasks for t in runs[task]]
    memory, _ = build_memories(
        [*failures, *success_runs],
        encoder,
        provenance=Provenance(data=data, encoder=encoder_spec),
    )
    judged = detector_with(replace(detector, rule=detector.rule or NOVELTY.name), memory, encoder)
    return Reference(detector=judged, modes=modes, runs=runs, notes=notes)


def _sample(trajectories: Sequence[Trajectory], count: int) -> list[Trajectory]:
    """At most `count` of `trajectories`, the same ones every time (ordered by a digest of their key)."""
    if len(trajectories) <= count:
        return list(trajectories)
    digest = lambda t: hashlib.blake2b(t.key.encode(), digest_size=8).digest()  # noqa: E731
    return sorted(trajectories, key=digest)[:count]
