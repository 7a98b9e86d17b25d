"""The deployment protocol (OOD + N deployment successes per task): the runs moved out of the test set join
the success memory and, where the memory has one, the signal memory, so both modalities see them."""

from __future__ import annotations

from pathlib import Path

import pytest
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureDetector, load_dataset, load_encoder
from robofailring.errors import SettingError
from robofailring.evaluation.deployment import deploy_successes
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.thinning import DEFAULT_STEP

LENGTH = 8


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("deployed") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2",),
        episodes=4,
        length=LENGTH,
        signals=True,
    )


def test_deployment_successes_join_the_signal_memory_too(dataset: Path, tmp_path: Path) -> None:
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    loaded = load_dataset(dataset)
    train, test = loaded.select(split="train"), loaded.select(split="test")
    memory, _ = build_memories(train, encoder, provenance=Provenance(data=dataset, encoder="pixels"))
    assert memory.signals is not None
    before = memory.signals.task("pick_cube")
    assert before is not None
    deployed, left, not_joined = deploy_successes(memory, test, 1, encoder, DEFAULT_STEP)
    (moved,) = [t for t in test if t.key not in {r.key for r in left}]
    assert not moved.is_failure
    assert deployed.signals is not None
    after = deployed.signals.task("pick_cube")
    assert after is not None
    assert len(after.vectors["success"]) == len(before.vectors["success"]) + moved.length
    assert moved.episode in after.rows["success"].episodes.tolist()
    assert moved.episode not in before.rows["success"].episodes.tolist()  # the memory given is unchanged
    assert not_joined == []  # its signals read well


def test_deployment_successes_join_the_camera_success_memory(dataset: Path, tmp_path: Path) -> None:
    """Each view of a moved run is a success run of the cameras' success memory, which the evaluation's
    detector then searches: the run's own frames match at S⁺ = 1 there, and not in the memory given."""
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    loaded = load_dataset(dataset)
    train, test = loaded.select(split="train"), loaded.select(split="test")
    memory, _ = build_memories(train, encoder, provenance=Provenance(data=dataset, encoder="pixels"))
    assert memory.successes is not None
    deployed, left, _ = deploy_successes(memory, test, 1, encoder, DEFAULT_STEP)
    (moved,) = [t for t in test if t.key not in {r.key for r in left}]
    views = {(moved.episode, view) for view in moved.views}
    assert deployed.successes is not None and len(views) == 3
    assert views <= {(run.episode, run.view) for run in deployed.successes.runs if run.kind == "success"}
    assert deployed.successes.success_runs == memory.successes.success_runs + len(views)
    assert not views & {
        (run.episode, run.view) for run in memory.successes.runs
    }  # the memory given unchanged
    judged = FailureDetector(deployed, encoder).run(moved)
    before = FailureDetector(memory, encoder).run(moved)
    for view in moved.views:
        assert judged.success_similarity[view][0] == pytest.approx(1.0, abs=1e-5)
        assert before.success_similarity[view][-1] < judged.success_similarity[view][-1]


@pytest.mark.parametrize("per_task", ["2", "1000000000"])
def test_deployment_successes_that_leave_a_task_no_test_success_are_refused(
    dataset: Path, tmp_path: Path, per_task: str
) -> None:
    """Issue 50: `--deployment-successes` as large as a task's test successes (2 here) or larger left none to
    test, and the evaluation reported its FPR as "—" without a word; it is refused, naming the task."""
    from fault_helpers import cli, refused

    out = tmp_path / "evaluation"
    found = cli(
        "evaluate",
        dataset,
        "--out",
        out,
        "--deployment-successes",
        per_task,
        "--cache-dir",
        tmp_path / "cache",
    )
    refused(
        found,
        2,
        f"--deployment-successes {per_task}",
        "task 'pick_cube'",
        "(its test data has 2)",
        "at most 1",
    )
    assert not out.exists()


def test_deployment_successes_without_a_success_memory_are_refused(dataset: Path, tmp_path: Path) -> None:
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "cache")
    loaded = load_dataset(dataset)
    train, test = loaded.select(split="train"), loaded.select(split="test")
    memory, _ = build_memories(
        train, encoder, provenance=Provenance(data=dataset, encoder="pixels"), successes=False
    )
    with pytest.raises(SettingError, match="no success memory for them to join"):
        deploy_successes(memory, test, 1, encoder, DEFAULT_STEP)
