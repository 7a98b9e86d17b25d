"""The deployment protocol of an evaluation (`evaluate --deployment-successes N`): per task, N test success runs
move into the success memory (and the signal memory, where the memory has one) and are not tested."""

from __future__ import annotations

from collections.abc import Sequence

from robofailring.data.model import Skipped, Trajectory
from robofailring.encoders import CachedEncoder
from robofailring.errors import SettingError
from robofailring.memory.failure import FailureMemory
from robofailring.memory.success import SuccessMemory


def deployed_runs(
    test: Sequence[Trajectory], per_task: int, *, tasks: set[str], successes: bool
) -> list[Trajectory]:
    """The `per_task` test success runs per task of `tasks` that `--deployment-successes` moves; SettingError
    where there is no success memory for them to join, or a task would keep no test success run to measure
    its false positive rate on (its FPR would read "—")."""
    if per_task and not successes:
        raise SettingError(
            f"--deployment-successes {per_task}: the memory has no success memory for them to join (built with "
            "--no-successes); build it with its success runs, or leave out --deployment-successes"
        )
    chosen: list[Trajectory] = []
    for task in sorted({t.task for t in test} & tasks) if per_task else ():
        runs = sorted((t for t in test if t.task == task and not t.is_failure), key=lambda t: t.key)
        if runs and per_task >= len(runs):
            raise SettingError(
                f"--deployment-successes {per_task} would leave task {task!r} no test success run to measure its "
                f"false positive rate on (its test data has {len(runs)}): give at most {len(runs) - 1}"
            )
        chosen += runs[:per_task]
    return chosen


def deploy_successes(
    memory: FailureMemory, test: list[Trajectory], per_task: int, encoder: CachedEncoder, step: float
) -> tuple[FailureMemory, list[Trajectory], list[Skipped]]:
    """Move `per_task` success runs per task from the test set into the success memory and, where the memory
    has one, the signal memory (in memory only); SettingError before anything is encoded (`deployed_runs`).
    The runs whose signals did not join (listed as skipped, as a build lists them) come third."""
    if per_task == 0:
        return memory, test, []
    successes = memory.successes
    chosen = deployed_runs(test, per_task, tasks=set(memory.tasks), successes=successes is not None)
    if successes is None or not chosen:  # (`deployed_runs` refuses a memory without successes)
        return memory, test, []
    deployed = memory.with_successes(
        successes.extended(SuccessMemory.build(chosen, encoder, step=step, pairing=memory.pairing))
    )
    unused: list[Skipped] = []
    if memory.signals is not None:  # the robot's signals of those runs join its signal memory too
        signals, unused = memory.signals.extended(chosen)
        deployed = deployed.with_signals(signals)
    keys = {t.key for t in chosen}
    return deployed, [t for t in test if t.key not in keys], unused
