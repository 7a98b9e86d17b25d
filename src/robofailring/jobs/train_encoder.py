"""The train-encoder job: an encoder trained on a dataset's training split and, with `randomize`,
on simulated episodes of the same tasks under random looks (`robofailring.sim.appearance`).

The randomised episodes match the data's image size and frames per episode, come from a seed of
their own (`RANDOMIZE_SEED` + the training seed) and are simulated once, then found in the cache.
The simulator (the `sim` extra) is imported only for them: training alone needs only `clip`.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Final

from robofailring.encoders.training import (
    TrainEncoderConfig,
    existing_encoder,
    train_encoder,
    training_trajectories,
)
from robofailring.errors import DataError, SettingError

if TYPE_CHECKING:
    from robofailring.jobs.simulate import DataShape

#: Added to the training seed for the randomised-look episodes: the demo and the benches simulate
#: their in-distribution sets from seed 0 and their out-of-distribution test sets from seed 1000.
RANDOMIZE_SEED: Final[int] = 5000


@dataclass(frozen=True)
class TrainEncoderJob:
    training: TrainEncoderConfig  # the data, the encoder folder and the recipe
    randomize: int = 0  # simulated episodes under random looks over the data's tasks (0: none)
    workers: int = 2  # simulation processes
    sim_cache: Path | None = None  # where the simulated set is cached (default <cache>/encoder-extra-data)

    def __post_init__(self) -> None:
        if self.randomize < 0 or self.workers < 1:
            raise SettingError(
                f"--randomize must be at least 0 and --workers at least 1, got {self.randomize} and {self.workers}"
            )


def simulator_shape(config: TrainEncoderConfig) -> DataShape:
    """The tasks, image side and most common frames per episode of the training split of `config.data`;
    a task the simulator does not have is a SettingError naming the data's tasks and the simulator's."""
    from robofailring.jobs.simulate import DataShape
    from robofailring.sim import TASKS

    trajectories = training_trajectories(config)
    if not trajectories:
        raise DataError(f"no trajectories in split {config.split!r} of {config.data.root}")
    tasks = tuple(sorted({t.task for t in trajectories}))
    foreign = [task for task in tasks if task not in TASKS]
    if foreign:
        raise SettingError(
            f"--randomize simulates the data's tasks, but {config.data.root} has tasks {list(tasks)} and the "
            f"simulator only {list(TASKS)} (it cannot simulate {foreign})"
        )
    lengths = Counter(len(frames) for t in trajectories for frames in t.views.values())
    first = next(frames[0] for t in trajectories for frames in t.views.values() if frames)
    height, width = first.load().shape[:2]
    return DataShape(tasks=tasks, image_size=max(height, width), frames=lengths.most_common(1)[0][0])


def run_train_encoder(
    job: TrainEncoderJob, *, reuse: bool = False, say: Callable[[str], None] | None = None
) -> Path:
    """Train (or with `reuse`, find) the encoder of `job`; returns its folder.

    The output folder and the data's tasks are checked before anything is simulated or trained.
    """
    config = job.training
    existing_encoder(Path(config.out))
    if job.randomize:
        from robofailring.jobs.simulate import extra_set
        from robofailring.sim import describe_dataset

        randomized = extra_set(
            simulator_shape(config),
            job.randomize,
            look="random",
            seed=RANDOMIZE_SEED + config.seed,
            workers=job.workers,
            cache=job.sim_cache,
        )
        if say:
            say(f"randomised looks: {describe_dataset(randomized)}")
        config = replace(config, extra_data=(*config.extra_data, randomized))
    return train_encoder(config, reuse=reuse, say=say)
