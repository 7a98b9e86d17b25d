"""FailureMemory: Algorithm 1 vectors, task-constrained Faiss search, storage, bad input."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from robofailring import CachedEncoder, FailureMemory, Frame, Outcome, Trajectory, load_dataset, load_encoder
from robofailring.errors import EncoderMismatchError, MemoryFormatError, SymbolError, UnknownTaskError
from robofailring.memory.failure import MemoryEntry
from robofailring.memory.pairs import pair_vectors


@pytest.fixture()
def built(aha_dataset: Path, encoder: CachedEncoder) -> tuple[FailureMemory, CachedEncoder, list[Trajectory]]:
    trajectories = list(load_dataset(aha_dataset))
    memory, _ = FailureMemory.build(trajectories, encoder)
    return memory, encoder, trajectories


def test_memory_vector_is_the_hand_computation(
    built: tuple[FailureMemory, CachedEncoder, list[Trajectory]],
) -> None:
    memory, _, trajectories = built
    encoder = load_encoder("pixels")
    trajectory = trajectories[3]
    for view, frames in trajectory.views.items():
        start, end = encoder.encode([frames[0].load(), frames[-1].load()])
        z_s, z_e = start / np.linalg.norm(start), end / np.linalg.norm(end)
        joined = np.concatenate([z_s, z_e])
        expected = joined / np.linalg.norm(joined)
        (row,) = [
            i for i, e in enumerate(memory.entries) if e.episode == trajectory.episode and e.view == view
        ]
        np.testing.assert_allclose(memory.vectors[row], expected, rtol=1e-5, atol=1e-6)
        assert memory.entries[row].start == str(frames[0].path)
        assert memory.entries[row].end == str(frames[-1].path)
    assert memory.dim == 1024
    assert len(memory) == 2 * 3 * 2 * 3  # tasks × symbols × episodes × views


def test_search_equals_brute_force_within_the_task(
    built: tuple[FailureMemory, CachedEncoder, list[Trajectory]],
) -> None:
    memory, _, _ = built
    rng = np.random.default_rng(0)
    queries = pair_vectors(rng.standard_normal((7, 512)), rng.standard_normal((7, 512)), pairing="concat")
    for task in memory.tasks:
        sims, ids = memory.search(queries, task, 4)
        members = np.array([i for i, e in enumerate(memory.entries) if e.task == task])
        brute = queries @ memory.vectors[members].T
        np.testing.assert_allclose(sims[:, 0], brute.max(axis=1), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(sims, -np.sort(-brute, axis=1)[:, :4], rtol=1e-5, atol=1e-6)
        assert all(memory.entries[i].task == task for i in ids.ravel())


def test_other_tasks_never_appear_even_when_closer(
    built: tuple[FailureMemory, CachedEncoder, list[Trajectory]],
) -> None:
    memory, _, _ = built
    push_rows = [i for i, e in enumerate(memory.entries) if e.task == "push_cube"]
    query = memory.vectors[push_rows[0]]  # identical to a push_cube entry: similarity 1 there
    sims, ids = memory.search(query, "pick_cube", 5)
    assert sims[0, 0] < 0.999
    assert {memory.entries[i].task for i in ids[0]} == {"pick_cube"}


def test_leave_one_out_hides_the_episode(
    built: tuple[FailureMemory, CachedEncoder, list[Trajectory]],
) -> None:
    memory, _, _ = built
    row = 0
    entry = memory.entries[row]
    sims, ids = memory.search(memory.vectors[row], entry.task, 3)
    assert ids[0, 0] == row and sims[0, 0] == pytest.approx(1.0, abs=1e-5)
    sims, ids = memory.search(memory.vectors[row], entry.task, 3, exclude_episode=entry.episode)
    assert all(memory.entries[i].episode != entry.episode for i in ids[0])
    assert (ids[0] >= 0).all()


def test_k_larger_than_task_pads(built: tuple[FailureMemory, CachedEncoder, list[Trajectory]]) -> None:
    memory, _, _ = built
    size = memory.task_size("pick_cube")
    sims, ids = memory.search(memory.vectors[0], "pick_cube", size + 3)
    assert (ids[0, :size] >= 0).all() and (ids[0, size:] == -1).all()
    assert np.isnan(sims[0, size:]).all()


def test_save_load_round_trip(
    built: tuple[FailureMemory, CachedEncoder, list[Trajectory]], tmp_path: Path
) -> None:
    memory, _, _ = built
    memory.save(tmp_path / "mem")
    manifest = json.loads((tmp_path / "mem" / "manifest.json").read_text())
    assert manifest["format_version"] == 2  # references relative to data_root
    assert (
        manifest["encoder"] == memory.encoder and manifest["dim"] == 1024 and manifest["count"] == len(memory)
    )
    loaded = FailureMemory.load(tmp_path / "mem")
    assert loaded.entries == memory.entries
    query = memory.vectors[::5]
    for task in memory.tasks:
        a, ia = memory.search(query, task, 4)
        b, ib = loaded.search(query, task, 4)
        np.testing.assert_array_equal(ia, ib)
        np.testing.assert_array_equal(a, b)


def test_unknown_symbol_is_rejected_before_encoding(cache_dir: Path, tmp_path: Path) -> None:
    frames = tuple(Frame(path=tmp_path / f"{i}.png") for i in range(3))  # never read
    bad = Trajectory(
        task="t", episode="e0", views={"front": frames}, symbol="rotation_w_wp1", outcome=Outcome.FAILURE
    )
    with pytest.raises(SymbolError, match="'w'"):
        FailureMemory.build([bad], CachedEncoder(load_encoder("pixels"), cache_dir=cache_dir))


def test_short_views_are_skipped_and_counted(aha_dataset: Path, cache_dir: Path) -> None:
    trajectory = next(iter(load_dataset(aha_dataset)))
    views = dict(trajectory.views)
    views["wrist"] = views["wrist"][:1]
    views["overhead"] = ()
    short = Trajectory(
        task=trajectory.task, episode="short", views=views, symbol="slip_wp3", outcome=Outcome.FAILURE
    )
    success = Trajectory(task=trajectory.task, episode="ok", views=views, outcome=Outcome.SUCCESS)
    memory, stats = FailureMemory.build(
        [short, success], CachedEncoder(load_encoder("pixels"), cache_dir=cache_dir)
    )
    assert [e.view for e in memory.entries] == ["front"]
    assert {(s["view"], s["frames"]) for s in stats.skipped_views} == {("wrist", 1), ("overhead", 0)}
    assert stats.ignored_non_failures == 1


def test_mismatch_unknown_task_and_corrupt_files(
    built: tuple[FailureMemory, CachedEncoder, list[Trajectory]], tmp_path: Path
) -> None:
    memory, _, _ = built
    with pytest.raises(EncoderMismatchError, match="open_clip:ViT-B-32:openai"):
        memory.check_encoder("open_clip:ViT-B-32:openai")
    with pytest.raises(UnknownTaskError, match="'open_drawer'"):
        memory.search(memory.vectors[0], "open_drawer", 3)
    memory.save(tmp_path / "mem")
    broken = tmp_path / "broken"
    shutil.copytree(tmp_path / "mem", broken)
    (broken / "index.faiss").write_bytes(b"not an index")
    with pytest.raises(MemoryFormatError, match=r"index\.faiss"):
        FailureMemory.load(broken)
    with pytest.raises(MemoryFormatError, match=r"manifest\.json is missing"):
        FailureMemory.load(tmp_path / "nothing")
    manifest = json.loads((tmp_path / "mem" / "manifest.json").read_text())
    manifest["format_version"] = 99
    (broken / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(MemoryFormatError, match="format_version 99"):
        FailureMemory.load(broken)


def test_interrupted_save_keeps_the_previous_memory(
    built: tuple[FailureMemory, CachedEncoder, list[Trajectory]],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    memory, _, _ = built
    target = tmp_path / "mem"
    memory.save(target)
    before = (target / "entries.jsonl").read_bytes()
    smaller = FailureMemory(memory.vectors[:2], memory.entries[:2], encoder=memory.encoder)

    def explode(*_: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr("robofailring.memory.folder.faiss.write_index", explode)
    with pytest.raises(OSError, match="disk full"):
        smaller.save(target)
    assert (target / "entries.jsonl").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "cache") == ["mem"]  # no temporary left


def test_entry_description_is_grounded() -> None:
    entry = MemoryEntry(task="t", symbol="rotation_x_wp1", episode="e", view="front", start="a", end="b")
    assert entry.description.endswith("at the initial stage (Waypoint 1)")
