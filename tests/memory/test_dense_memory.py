"""The dense failure memory: (I_0 ‖ I_τ) entries from each failure's onset on, thinned, with their frame kept;
the paper's memory (`end`) as it always was; both recorded in the manifest and read back."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureMemory, load_dataset
from robofailring.data.model import Trajectory
from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import DataError, MemoryFormatError, SettingError
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.builder import Provenance, add_to, build_memories
from robofailring.memory.folder import ENTRIES, MANIFEST
from robofailring.memory.format import ENTRY_FIELDS
from robofailring.memory.info import MemoryInfo
from robofailring.memory.pairs import CONCAT, pair_vectors
from robofailring.memory.recipe import MemoryRecipe

LENGTH = 9
ONSET = 3


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Failures of one task whose onset is frame 3 of 9, and success runs."""
    return write_project_dataset(
        tmp_path_factory.mktemp("dense") / "data",
        tasks=("pick_cube",),
        symbols=("grasp_wp2", "slip_wp3"),
        episodes=2,
        length=LENGTH,
        onset=ONSET,
    )


def _build(data: Path, encoder: CachedEncoder, failure_frames: str, **options: Any) -> FailureMemory:
    trajectories = list(load_dataset(data))
    provenance = Provenance(data=data, encoder="pixels")
    recipe = MemoryRecipe(failure_frames=failure_frames, **options)
    memory, _ = build_memories(trajectories, encoder, provenance=provenance, recipe=recipe)
    return memory


def _failures(data: Path) -> list[Trajectory]:
    return [t for t in load_dataset(data) if t.is_failure]


def test_dense_entries_run_from_the_onset_to_the_end_each_its_own_pair(
    data: Path, encoder: CachedEncoder
) -> None:
    memory = _build(data, encoder, "dense")
    failures = _failures(data)
    assert all(t.onset_frame == ONSET for t in failures)
    by_view: dict[tuple[str, str], list[int]] = {}
    for row, entry in enumerate(memory.entries):
        by_view.setdefault((entry.episode, entry.view), []).append(row)
    assert len(by_view) == sum(len(t.views) for t in failures) == 12
    for trajectory in failures:
        for view, frames in trajectory.views.items():
            rows = by_view[(trajectory.episode, view)]
            entries = [memory.entries[row] for row in rows]
            # every synthetic frame differs from the last, so thinning keeps all of onset … end
            assert [e.frame for e in entries] == list(range(ONSET, LENGTH))
            assert {e.length for e in entries} == {LENGTH}
            assert [e.end for e in entries] == [frames[t].reference for t in range(ONSET, LENGTH)]
            assert {e.start for e in entries} == {frames[0].reference}
            embedded = encoder.encode_frames(list(frames))
            expected = pair_vectors(
                np.repeat(embedded[:1], LENGTH - ONSET, axis=0), embedded[ONSET:], pairing=memory.pairing
            )
            np.testing.assert_allclose(memory.vectors[rows], expected, atol=1e-6)
    assert (memory.manifest.failure_frames, memory.manifest.failure_step) == ("dense", 0.002)
    assert memory.entries[rows[-1]].moment == f"frame {LENGTH - 1} of {LENGTH} (end of the run)"
    assert memory.entries[rows[0]].moment == f"frame {ONSET} of {LENGTH} (33 %)"


def test_without_an_onset_dense_starts_at_frame_one(tmp_path: Path, encoder: CachedEncoder) -> None:
    data = write_project_dataset(
        tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=1, length=5
    )
    memory = _build(data, encoder, "dense")
    assert [e.frame for e in memory.entries if e.view == "front"] == [1, 2, 3, 4]


def test_thinning_drops_repeated_frames_and_keeps_the_end(tmp_path: Path, encoder: CachedEncoder) -> None:
    """Frames 1-7 of each failure view are one image: only frame 1 of them stays, and the end (8)."""
    data = write_project_dataset(
        tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=1, length=LENGTH
    )
    for trajectory in _failures(data):
        for frames in trajectory.views.values():
            for t in range(2, LENGTH - 1):
                shutil.copyfile(frames[1].reference, frames[t].reference)
    thinned = _build(data, encoder, "dense")
    assert {e.view: [] for e in thinned.entries}.keys() == {"front", "overhead", "wrist"}
    for view in ("front", "overhead", "wrist"):
        assert [e.frame for e in thinned.entries if e.view == view] == [1, LENGTH - 1]
    every = _build(data, encoder, "dense", success_step=0.0)  # step 0 keeps every frame
    assert [e.frame for e in every.entries if e.view == "front"] == list(range(1, LENGTH))
    assert every.manifest.failure_step == 0.0


def test_end_is_the_papers_memory_one_pair_of_first_and_last_frame(
    data: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    memory = _build(data, encoder, "end", pairing=CONCAT)
    failures = _failures(data)
    firsts = [frames[0] for t in failures for frames in t.views.values()]
    lasts = [frames[-1] for t in failures for frames in t.views.values()]
    expected = pair_vectors(encoder.encode_frames(firsts), encoder.encode_frames(lasts), pairing="concat")
    assert np.array_equal(memory.vectors, expected)  # bit for bit: the vectors every memory had before
    assert [(e.start, e.end, e.frame, e.length) for e in memory.entries] == [
        (first.reference, last.reference, None, None) for first, last in zip(firsts, lasts, strict=True)
    ]
    assert memory.manifest.failure_frames == "end" and memory.manifest.failure_step is None
    paper, _ = FailureMemory.build(load_dataset(data), encoder)  # the paper's memory alone: the same
    assert np.array_equal(paper.vectors, memory.vectors) and paper.manifest.failure_frames == "end"

    saved = memory.save(tmp_path / "end")
    rows = [json.loads(line) for line in (saved / ENTRIES).read_text().splitlines()]
    assert all(set(row) == set(ENTRY_FIELDS) for row in rows)  # no frame or length written
    assert FailureMemory.load(saved).entries[0].moment == "end of the run"


def test_a_saved_dense_memory_keeps_each_entrys_frame_and_length(
    data: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    memory = _build(data, encoder, "dense")
    saved = memory.save(tmp_path / "dense")
    rows = [json.loads(line) for line in (saved / ENTRIES).read_text().splitlines()]
    assert [(row["frame"], row["length"]) for row in rows[: LENGTH - ONSET]] == [
        (t, LENGTH) for t in range(ONSET, LENGTH)
    ]
    manifest = json.loads((saved / MANIFEST).read_text())
    assert (manifest["failure_frames"], manifest["failure_step"]) == ("dense", 0.002)
    loaded = FailureMemory.load(saved)
    assert [(e.frame, e.length, e.end) for e in loaded.entries] == [
        (e.frame, e.length, e.end) for e in memory.entries
    ]
    assert loaded.manifest.failure_mode == "dense"
    assert MemoryInfo.read(saved).to_dict()["failure_frames"] == "dense"


def test_a_memory_from_before_the_choice_loads_as_the_papers(
    data: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    """No `failure_frames` in its manifest, no frame in its entries: end entries, grown as end entries."""
    old = _build(data, encoder, "end").save(tmp_path / "old")
    manifest = json.loads((old / MANIFEST).read_text())
    del manifest["failure_frames"]
    (old / MANIFEST).write_text(json.dumps(manifest))
    loaded = FailureMemory.load(old)
    assert loaded.manifest.failure_frames is None and loaded.manifest.failure_mode == "end"
    assert all(e.frame is None and e.length is None for e in loaded.entries)
    assert "failure_frames" not in loaded.manifest.to_dict()  # rewritten as it was read
    info = MemoryInfo.read(old).to_text()
    assert "failures    end (the paper's), 12 entries from 12 failure views" in info

    other = write_project_dataset(
        tmp_path / "more", tasks=("pick_cube",), symbols=("wrong_object",), episodes=1, length=LENGTH
    )
    grown, stats = add_to(loaded, _failures(other), encoder)
    added = grown.entries[len(loaded) :]
    assert len(added) == stats.entries == 3 and all(e.frame is None for e in added)  # end, like the memory
    assert grown.manifest.failure_mode == "end"


def test_a_dense_memory_grows_dense(data: Path, encoder: CachedEncoder, tmp_path: Path) -> None:
    memory = _build(data, encoder, "dense", success_step=0.0)
    other = write_project_dataset(
        tmp_path / "more", tasks=("pick_cube",), symbols=("wrong_object",), episodes=1, length=5
    )
    grown, _ = add_to(memory, _failures(other), encoder, success_step=0.5)
    added = grown.entries[len(memory) :]
    assert [e.frame for e in added if e.view == "front"] == [
        1,
        2,
        3,
        4,
    ]  # the memory's own step 0 thins nothing
    assert (grown.manifest.failure_frames, grown.manifest.failure_step) == ("dense", 0.0)


def test_build_memory_refuses_to_grow_a_memory_into_another_kind(data: Path, tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    out = tmp_path / "memory"
    build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=out,
            recipe=MemoryRecipe.chosen("pixels", failure_frames="end"),
            placement=EncoderPlacement(cache_dir=cache),
            split="train",
        )
    )
    with pytest.raises(SettingError, match="holds end failure frames"):
        build_memory(
            BuildMemoryConfig(
                data=DataSelection(data),
                out=out,
                recipe=MemoryRecipe.chosen("pixels", failure_frames="dense"),
                placement=EncoderPlacement(cache_dir=cache),
                split="test",
                add_to=True,
            )
        )
    with pytest.raises(SettingError, match="end or dense, got 'sparse'"):
        BuildMemoryConfig(
            data=DataSelection(data), out=out, recipe=MemoryRecipe.chosen("pixels", failure_frames="sparse")
        )
    assert FailureMemory.load(out).manifest.failure_mode == "end"  # nothing was written


@pytest.mark.parametrize(
    ("extra", "said"),
    [
        ({"frame": -1, "length": 9}, "'frame' must lie in 0 … length − 1 = 8, not -1"),
        ({"frame": 9, "length": 9}, "'frame' must lie in 0 … length − 1 = 8, not 9"),
        ({"frame": "3", "length": 9}, "'frame' must be a whole number"),
        ({"frame": 2.5, "length": 9}, "'frame' must be a whole number"),
        ({"frame": True, "length": 9}, "'frame' must be a whole number"),
        ({"frame": 3}, "'length' must be a whole number (with 'frame' and 'length' together)"),
        ({"length": 9}, "'frame' must be a whole number"),
    ],
)
def test_a_bad_frame_in_entries_is_named_by_file_and_line(
    data: Path, encoder: CachedEncoder, tmp_path: Path, extra: dict[str, object], said: str
) -> None:
    saved = _build(data, encoder, "end").save(tmp_path / "memory")
    rows = [json.loads(line) for line in (saved / ENTRIES).read_text().splitlines()]
    rows[1] |= extra
    (saved / ENTRIES).write_text("".join(json.dumps(row) + "\n" for row in rows))
    with pytest.raises(MemoryFormatError) as raised:
        FailureMemory.load(saved)
    assert f"{saved / ENTRIES}:2:" in str(raised.value) and said in str(raised.value)


def test_a_manifest_naming_another_kind_of_failure_memory_is_refused(
    data: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    saved = _build(data, encoder, "end").save(tmp_path / "memory")
    manifest = json.loads((saved / MANIFEST).read_text())
    (saved / MANIFEST).write_text(json.dumps(manifest | {"failure_frames": "sparse"}))
    with pytest.raises(
        MemoryFormatError, match="'failure_frames' is 'sparse', this version reads end or dense"
    ):
        FailureMemory.load(saved)
    (saved / MANIFEST).write_text(json.dumps(manifest | {"failure_frames": "dense", "failure_step": -1}))
    with pytest.raises(MemoryFormatError, match="'failure_step' must be a cosine step within"):
        FailureMemory.load(saved)


def test_no_failure_view_gives_no_entry_in_either_kind(tmp_path: Path, encoder: CachedEncoder) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), symbols=(), episodes=2, length=4)
    for kind in ("end", "dense"):
        memory = _build(data, encoder, kind)
        assert len(memory) == 0 and memory.vectors.shape == (0, 2 * encoder.dim)
    with pytest.raises(DataError):
        build_memory(
            BuildMemoryConfig(
                data=DataSelection(data),
                out=tmp_path / "m",
                recipe=MemoryRecipe.chosen("pixels"),
                success_memory=False,
            )
        )
