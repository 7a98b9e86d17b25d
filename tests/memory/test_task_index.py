"""task_index: exact and approximate task-constrained search, batching, leave-one-out, storage."""

from __future__ import annotations

import json
from pathlib import Path

import faiss
import numpy as np
import pytest

from robofailring.errors import MemoryFormatError, SettingError
from robofailring.memory.index import (
    APPROXIMATE_ABOVE,
    FLAT,
    IVF_PQFS,
    IVF_SQ8,
    IndexSpec,
    TaskIndex,
    TaskIndexSet,
    choose_spec,
)
from robofailring.memory.success import SuccessMemory, SuccessRun

DIM = 64
# ivf_pqfs: the exact nearest entry is among its 10 best this often here (0.84 measured); its own top-1
# is often a near-tie (the exact top two differ by 0.0001 in median), so S⁺ error is what is bounded
RECALL_AT_10 = 0.7


def unit(rows: np.ndarray) -> np.ndarray:
    return (rows / np.linalg.norm(rows, axis=-1, keepdims=True)).astype(np.float32)


def smooth_runs(task: int, runs: int, frames: int, seed: int = 0, dim: int = DIM) -> np.ndarray:
    """(runs, frames, dim): runs of one task wander smoothly around the task's centre."""
    rng = np.random.default_rng(1000 * task + seed)
    centre = 3.0 * unit(np.random.default_rng(task).standard_normal(dim))
    path = np.random.default_rng(50 + task).standard_normal((4, dim)) * 0.5
    out = np.empty((runs, frames, dim), np.float32)
    for run in range(runs):
        t = np.linspace(0, 1, frames)[:, None] ** np.exp(rng.normal(0, 0.2))
        basis = np.concatenate([np.cos(np.pi * t * [1, 2]), np.sin(np.pi * t * [1, 2])], axis=1)
        out[run] = unit(
            centre
            + basis @ path
            + 0.3 * unit(rng.standard_normal(dim))
            + 0.05 * rng.standard_normal((frames, dim))
        )
    return out


@pytest.fixture(scope="module")
def memory() -> tuple[np.ndarray, list[str], list[str]]:
    """3 tasks × 30 runs × 40 frames; rows of a task are interleaved with the others' rows."""
    blocks = [smooth_runs(task, 30, 40) for task in range(3)]
    vectors = np.stack(blocks, axis=1).reshape(-1, DIM)  # run-major, tasks interleaved
    tasks = [f"task{task}" for run in range(30) for task in range(3) for _ in range(40)]
    episodes = [f"ep{run}" for run in range(30) for _ in range(3) for _ in range(40)]
    return vectors, tasks, episodes


def brute_force(
    vectors: np.ndarray,
    tasks: list[str],
    episodes: list[str],
    queries: np.ndarray,
    task: str,
    hide: str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    members = np.array(
        [i for i, (t, e) in enumerate(zip(tasks, episodes, strict=True)) if t == task and e != hide]
    )
    scores = queries @ vectors[members].T
    order = np.argsort(-scores, axis=1, kind="stable")
    return np.take_along_axis(scores, order, axis=1), members[order]


def test_flat_search_is_brute_force_within_the_task(memory: tuple[np.ndarray, list[str], list[str]]) -> None:
    vectors, tasks, episodes = memory
    index = TaskIndexSet.build(vectors, tasks, episodes, kind=FLAT)
    queries = smooth_runs(1, 2, 40, seed=9).reshape(-1, DIM)
    sims, ids = index.search(queries, "task1", 4)
    expected_sims, expected_ids = brute_force(vectors, tasks, episodes, queries, "task1")
    np.testing.assert_allclose(sims, expected_sims[:, :4], rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(ids[:, 0], expected_ids[:, 0])


def test_ivf_sq8_agrees_with_flat_on_clustered_data(memory: tuple[np.ndarray, list[str], list[str]]) -> None:
    """S⁺ (top-1) of held-out runs within 0.01 of exact, and mostly the same entry."""
    vectors, tasks, episodes = memory
    exact = TaskIndexSet.build(vectors, tasks, episodes, kind=FLAT)
    approximate = TaskIndexSet.build(vectors, tasks, episodes, kind=IVF_SQ8)
    assert approximate.by_task["task0"].spec.kind == IVF_SQ8
    for task in range(3):
        queries = smooth_runs(task, 3, 40, seed=7).reshape(-1, DIM)
        exact_sims, exact_ids = exact.search(queries, f"task{task}", 1)
        sims, ids = approximate.search(queries, f"task{task}", 1)
        assert np.abs(sims - exact_sims).max() <= 0.01
        assert np.mean(ids == exact_ids) >= 0.8


@pytest.mark.parametrize("kind", [FLAT, IVF_SQ8, IVF_PQFS])
def test_search_never_crosses_tasks(memory: tuple[np.ndarray, list[str], list[str]], kind: str) -> None:
    vectors, tasks, episodes = memory
    index = TaskIndexSet.build(vectors, tasks, episodes, kind=kind)
    other = vectors[[i for i, t in enumerate(tasks) if t == "task2"][:50]]  # exact copies of task2 rows
    for task in ("task0", "task1"):
        sims, ids = index.search(other, task, 10)
        assert np.all(ids >= 0)
        assert {tasks[i] for i in ids.ravel()} == {task}
        assert sims.max() < 0.999  # the identical rows of task2 were not found
    assert index.tasks == ["task0", "task1", "task2"]
    assert len(index) == len(vectors)


@pytest.mark.parametrize("kind", [FLAT, IVF_SQ8, IVF_PQFS])
def test_leave_one_out_hides_the_episode(memory: tuple[np.ndarray, list[str], list[str]], kind: str) -> None:
    vectors, tasks, episodes = memory
    index = TaskIndexSet.build(vectors, tasks, episodes, kind=kind)
    own = [i for i, (t, e) in enumerate(zip(tasks, episodes, strict=True)) if t == "task0" and e == "ep3"]
    queries = vectors[own]  # the episode's own frames would be their own nearest neighbours
    sims, ids = index.search(queries, "task0", 5)
    assert np.array_equal(ids[:, 0], own) or kind != FLAT
    sims, ids = index.search(queries, "task0", 5, exclude_episode="ep3")
    assert not set(ids.ravel().tolist()) & set(own)
    assert {episodes[i] for i in ids.ravel()} <= {f"ep{run}" for run in range(30)} - {"ep3"}
    expected_sims, expected_ids = brute_force(vectors, tasks, episodes, queries, "task0", hide="ep3")
    if kind == FLAT:
        np.testing.assert_allclose(sims, expected_sims[:, :5], rtol=1e-5, atol=1e-6)
        np.testing.assert_array_equal(ids[:, 0], expected_ids[:, 0])
    else:
        assert np.abs(sims[:, 0] - expected_sims[:, 0]).max() <= 0.01
    # the other episode, then the first again: the cached selector follows the episode asked for
    _, other_ids = index.search(queries, "task0", 5, exclude_episode="ep4")
    assert not {episodes[i] for i in other_ids.ravel()} & {"ep4"}
    _, again = index.search(queries, "task0", 5, exclude_episode="ep3")
    np.testing.assert_array_equal(again, ids)


def test_rows_are_padded_when_the_task_has_fewer_than_k() -> None:
    vectors = unit(np.random.default_rng(0).standard_normal((5, DIM)))
    index = TaskIndexSet.build(vectors, ["a", "a", "a", "b", "b"], ["e1", "e1", "e2", "e3", "e3"], kind=FLAT)
    sims, ids = index.search(vectors[:2], "a", 4, exclude_episode="e1")
    np.testing.assert_array_equal(ids, [[2, -1, -1, -1], [2, -1, -1, -1]])
    assert np.isnan(sims[:, 1:]).all()
    np.testing.assert_allclose(sims[:, 0], vectors[:2] @ vectors[2], rtol=1e-5)
    sims, ids = index.search(vectors[3:4], "b", 2, exclude_episode="e3")
    assert (ids == -1).all() and np.isnan(sims).all()


@pytest.mark.parametrize("kind", [FLAT, IVF_SQ8, IVF_PQFS])
def test_one_batched_call_equals_one_call_per_view(
    memory: tuple[np.ndarray, list[str], list[str]], kind: str
) -> None:
    vectors, tasks, episodes = memory
    index = TaskIndexSet.build(vectors, tasks, episodes, kind=kind)
    step = smooth_runs(2, 3, 40, seed=5)[:, 17]  # 3 views of one frame
    sims, ids = index.search(step, "task2", 5, exclude_episode="ep1")
    for view in range(3):
        view_sims, view_ids = index.search(step[view], "task2", 5, exclude_episode="ep1")
        np.testing.assert_array_equal(view_ids[0], ids[view])
        np.testing.assert_allclose(view_sims[0], sims[view], rtol=1e-6)


@pytest.mark.parametrize("kind", [FLAT, IVF_SQ8, IVF_PQFS])
def test_save_and_load_keep_kind_parameters_and_results(
    memory: tuple[np.ndarray, list[str], list[str]], kind: str, tmp_path: Path
) -> None:
    vectors, tasks, episodes = memory
    index = TaskIndexSet.build(vectors, tasks, episodes, kind=kind, nprobe=3)
    section = index.write(tmp_path, "success")
    section = json.loads(json.dumps(section))  # as the manifest stores it
    assert section["task1"]["count"] == 1200 and section["task1"]["file"] == "success.1.faiss"
    assert section["task1"]["kind"] == kind
    if kind != FLAT:
        assert (
            section["task1"]["nprobe"] == 3 and section["task1"]["nlist"] == index.by_task["task1"].spec.nlist
        )
    loaded = TaskIndexSet.read(tmp_path, section, tasks, episodes)
    assert loaded.by_task["task1"].spec == index.by_task["task1"].spec
    queries = smooth_runs(1, 1, 40, seed=3)[0]
    for hide in (None, "ep2"):
        expected = index.search(queries, "task1", 3, exclude_episode=hide)
        found = loaded.search(queries, "task1", 3, exclude_episode=hide)
        np.testing.assert_array_equal(found[1], expected[1])
        np.testing.assert_array_equal(found[0], expected[0])


def test_loading_rejects_a_manifest_that_does_not_match(
    memory: tuple[np.ndarray, list[str], list[str]], tmp_path: Path
) -> None:
    vectors, tasks, episodes = memory
    section = TaskIndexSet.build(vectors, tasks, episodes, kind=FLAT).write(tmp_path, "success")
    wrong_kind = {**section, "task0": {**section["task0"], "kind": IVF_SQ8, "nlist": 4, "nprobe": 2}}
    with pytest.raises(MemoryFormatError, match=r"success\.0\.faiss.*manifest says"):
        TaskIndexSet.read(tmp_path, wrong_kind, tasks, episodes)
    with pytest.raises(MemoryFormatError, match="task0"):
        TaskIndexSet.read(tmp_path, {**section, "task0": {**section["task0"], "count": 7}}, tasks, episodes)
    with pytest.raises(MemoryFormatError, match="tasks"):
        TaskIndexSet.read(tmp_path, {"task0": section["task0"]}, tasks, episodes)
    (tmp_path / "success.2.faiss").write_bytes(b"not an index")
    with pytest.raises(MemoryFormatError, match=r"success\.2\.faiss"):
        TaskIndexSet.read(tmp_path, section, tasks, episodes)


@pytest.mark.parametrize("kind", [IVF_SQ8, IVF_PQFS])
def test_loading_refuses_an_index_file_that_probes_more_lists_than_it_has(
    memory: tuple[np.ndarray, list[str], list[str]], kind: str, tmp_path: Path
) -> None:
    """nprobe above nlist is a damaged file, named as one (Faiss's fast-scan IVF returns garbage there)."""
    vectors, tasks, episodes = memory
    index = TaskIndexSet.build(vectors, tasks, episodes, kind=kind, nprobe=3)
    section = index.write(tmp_path, "success")
    stored = index.by_task["task1"].index
    lists = faiss.downcast_index(stored.base_index) if kind == IVF_PQFS else stored
    lists.nprobe = lists.nlist + 1
    faiss.write_index(stored, str(tmp_path / "success.1.faiss"))
    with pytest.raises(MemoryFormatError, match=r"success\.1\.faiss: .*nprobe <= nlist"):
        TaskIndexSet.read(tmp_path, section, tasks, episodes)


def test_choose_spec_picks_exact_search_for_small_tasks() -> None:
    assert choose_spec(APPROXIMATE_ABOVE) == IndexSpec(FLAT)
    large = choose_spec(APPROXIMATE_ABOVE + 1)
    assert large.kind == IVF_PQFS and 1 <= large.nprobe <= large.nlist
    assert large.pq_m == 1024 // 16 and large.k_factor >= 1
    assert choose_spec(1_000_000, kind=IVF_SQ8).nlist == 2000
    assert choose_spec(1_000_000).nlist == round((16 * 1_000_000 * 32 / 4096) ** 0.5)  # 354
    assert choose_spec(250_000).nlist == 177 and choose_spec(250_000, dim=512).pq_m == 32
    assert choose_spec(100, kind=IVF_SQ8).nlist == 100 // 39
    assert choose_spec(10, kind=FLAT, approximate_above=1) == IndexSpec(FLAT)
    with pytest.raises(SettingError, match="hnsw"):
        choose_spec(10, kind="hnsw")
    with pytest.raises(SettingError, match="nprobe"):
        IndexSpec(IVF_SQ8, nlist=4, nprobe=5)
    with pytest.raises(MemoryFormatError, match="bad index description"):
        IndexSpec.from_dict({"kind": "ivf_sq8"})
    assert IndexSpec.from_dict(IndexSpec(IVF_SQ8, nlist=8, nprobe=2).to_dict()) == IndexSpec(IVF_SQ8, 8, 2)
    with pytest.raises(SettingError, match="kind"):
        TaskIndexSet.build(np.zeros((1, DIM), np.float32), ["a"], ["e"], kind="hnsw")


def test_task_index_rejects_mismatched_ids() -> None:
    vectors = unit(np.random.default_rng(1).standard_normal((4, DIM)))
    with pytest.raises(MemoryFormatError, match="4 entries for 3 ids"):
        TaskIndex.build(vectors, np.arange(3), ["e"] * 3)


LARGE_DIM = 256


@pytest.fixture(scope="module")
def large_task() -> tuple[np.ndarray, list[str], list[str]]:
    """A 20,000-entry task (50 runs × 400 frames) beside a 2,000-entry one, 256-d."""
    large = smooth_runs(0, 50, 400, dim=LARGE_DIM).reshape(-1, LARGE_DIM)
    small = smooth_runs(1, 5, 400, dim=LARGE_DIM).reshape(-1, LARGE_DIM)
    tasks = ["large"] * len(large) + ["small"] * len(small)
    episodes = [f"ep{row // 400}" for row in range(len(large))] + [
        f"s{row // 400}" for row in range(len(small))
    ]
    return np.concatenate([large, small]), tasks, episodes


def test_auto_picks_ivf_pqfs_for_a_large_task_within_the_s_plus_budget(
    large_task: tuple[np.ndarray, list[str], list[str]],
) -> None:
    """S⁺ (top-1 similarity) of held-out runs within 0.01 of exact search; a small task stays exact."""
    vectors, tasks, episodes = large_task
    index = TaskIndexSet.build(vectors, tasks, episodes, approximate_above=5_000)
    spec = index.by_task["large"].spec
    assert spec == choose_spec(20_000, dim=LARGE_DIM) and spec.kind == IVF_PQFS
    assert spec.pq_m == LARGE_DIM // 16 and spec.nlist == 50  # √(16 · 20,000 · 8 B / (4 · 256))
    assert index.by_task["small"].spec == IndexSpec(FLAT)
    exact = TaskIndexSet.build(vectors, tasks, episodes, kind=FLAT)
    queries = smooth_runs(0, 4, 400, seed=11, dim=LARGE_DIM).reshape(-1, LARGE_DIM)[::4]
    exact_sims, _ = exact.search(queries, "large", 1)
    sims, ids = index.search(queries, "large", 1)
    assert np.abs(sims - exact_sims).max() <= 0.01
    _, exact_ten = exact.search(queries, "large", 10)
    _, ten = index.search(queries, "large", 10)
    assert np.mean([exact_ten[row, 0] in ten[row] for row in range(len(queries))]) >= RECALL_AT_10
    # the re-ranked similarity is the entry's own (8-bit codes), not the PQ estimate
    np.testing.assert_allclose(sims[:, 0], np.sum(queries * vectors[ids[:, 0]], axis=1), atol=2e-3)
    small_queries = smooth_runs(1, 1, 400, seed=12, dim=LARGE_DIM)[0]
    np.testing.assert_array_equal(
        index.search(small_queries, "small", 3)[1], exact.search(small_queries, "small", 3)[1]
    )
    assert index.by_task["large"].nbytes < exact.by_task["large"].nbytes / 3  # 8-bit refine codes


@pytest.mark.parametrize("kind", [IVF_PQFS, IVF_SQ8])
def test_a_success_memory_with_an_approximate_index_loads_back_identically(
    large_task: tuple[np.ndarray, list[str], list[str]], kind: str, tmp_path: Path
) -> None:
    """Written and read as a memory folder: same manifest, same S⁺ and rows (ivf_sq8: older folders)."""
    vectors, tasks, episodes = large_task
    runs = [
        SuccessRun(task, episode, "front", tuple(f"frame{row}" for row in range(start, start + 400)))
        for start, task, episode in zip(
            range(0, len(vectors), 400), tasks[::400], episodes[::400], strict=True
        )
    ]
    index = TaskIndexSet.build(vectors, tasks, episodes, kind=kind)
    memory = SuccessMemory(vectors, runs, dim=LARGE_DIM, index=index)
    memory.write(tmp_path)
    section = json.loads(json.dumps(memory.manifest()))
    assert section["index"]["large"]["kind"] == kind
    loaded = SuccessMemory.read(tmp_path, section, LARGE_DIM)
    assert loaded.vectors is None and loaded.manifest() == memory.manifest()
    queries = smooth_runs(0, 2, 400, seed=13, dim=LARGE_DIM).reshape(-1, LARGE_DIM)[::8]
    for hide in (None, "ep3"):
        expected = memory.search(queries, "large", exclude_episode=hide)
        found = loaded.search(queries, "large", exclude_episode=hide)
        np.testing.assert_array_equal(found[1], expected[1])
        np.testing.assert_array_equal(found[0], expected[0])
