"""Pairings: the paper's concatenation and the change since the first frame, for entries and queries alike."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import MemoryFormatError, SettingError
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.pairs import CHANGE, CONCAT, change_of, check_pairing, pair_vectors
from robofailring.memory.recipe import DEFAULT_RECIPE, MemoryRecipe


def _unit(rows: np.ndarray) -> np.ndarray:
    return rows / np.linalg.norm(rows, axis=1, keepdims=True)


def test_the_two_pairings_of_a_first_and_a_current_frame() -> None:
    rng = np.random.default_rng(0)
    start, end = rng.standard_normal((5, 8)), rng.standard_normal((5, 8))
    z0, zt = _unit(start), _unit(end)
    np.testing.assert_allclose(
        pair_vectors(start, end, pairing=CONCAT), _unit(np.hstack([z0, zt])), atol=1e-6
    )
    np.testing.assert_allclose(
        pair_vectors(start, end, pairing=CHANGE), _unit(np.hstack([0.5 * z0, zt - z0])), atol=1e-6
    )
    # at t = 0 nothing has changed: the vector is the first frame alone
    first = pair_vectors(start, start, pairing=CHANGE)
    np.testing.assert_allclose(first, np.hstack([z0, np.zeros_like(z0)]), atol=1e-6)
    # what changed since the first frame, read back from either pairing
    for pairing in (CONCAT, CHANGE):
        np.testing.assert_allclose(
            change_of(pair_vectors(start, end, pairing=pairing), pairing=pairing), _unit(zt - z0), atol=1e-5
        )
    assert not change_of(first, pairing=CHANGE).any()
    with pytest.raises(ValueError, match="odd dimension 5"):
        change_of(np.ones((2, 5)), pairing=CONCAT)


def test_a_look_that_shifts_every_frame_alike_leaves_the_change_pairing_nearer() -> None:
    """A new look (a colour cast) moves the first and the current frame the same way: the change half
    is untouched, so the pair stays nearer its in-distribution self than the paper's concatenation."""
    rng = np.random.default_rng(1)
    start, end = _unit(rng.standard_normal((200, 16))), _unit(rng.standard_normal((200, 16)))
    cast = 0.6 * _unit(rng.standard_normal((1, 16)))
    moved_start, moved_end = start + cast, end + cast

    def kept(pairing: str) -> float:
        own = pair_vectors(start, end, pairing=pairing)
        moved = pair_vectors(moved_start, moved_end, pairing=pairing)
        return float(np.mean(np.sum(own * moved, axis=1)))

    assert kept(CHANGE) > kept(CONCAT)


def test_pairing_settings_are_checked() -> None:
    assert check_pairing("change") == CHANGE and DEFAULT_RECIPE.pairing == CHANGE
    with pytest.raises(SettingError, match="pairing must be concat or change, got 'diff'"):
        check_pairing("diff")
    with pytest.raises(SettingError, match="pairing must be concat or change"):
        pair_vectors(np.ones((1, 4)), np.ones((1, 4)), pairing="diff")


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(
        tmp_path_factory.mktemp("pairs") / "data", tasks=("pick_cube",), episodes=2, length=6
    )


@pytest.mark.parametrize("pairing", [CONCAT, CHANGE])
def test_entries_and_queries_are_paired_alike(data: Path, tmp_path: Path, pairing: str) -> None:
    build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=tmp_path / "m",
            recipe=MemoryRecipe.chosen("pixels", pairing=pairing),
            placement=EncoderPlacement(cache_dir=tmp_path / "c"),
            split="train",
        )
    )
    stored = json.loads((tmp_path / "m" / "manifest.json").read_text(encoding="utf-8"))
    assert stored["pairing"] == pairing
    loaded = FailureMemory.load(tmp_path / "m")
    assert loaded.pairing == pairing and loaded.successes is not None
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path / "c")
    failure = next(t for t in load_dataset(data).select(split="train") if t.is_failure)
    trace = FailureDetector(loaded, encoder).run(failure)
    # its own entries are in the memory: each of its frames meets its own vector, S⁻ = 1, S⁺ = 1 at frame 0
    for view in trace.views:
        assert trace.similarity[view][-1] == pytest.approx(1.0, abs=1e-5)
        assert trace.success_similarity[view][0] == pytest.approx(1.0, abs=1e-5)
    embeddings = encoder.encode_frames(list(failure.views[trace.views[0]]))
    expected = pair_vectors(embeddings[:1], embeddings[-1:], pairing=pairing)
    assert np.max(loaded.vectors @ expected[0]) == pytest.approx(1.0, abs=1e-5)


def test_a_memory_built_before_pairings_reads_as_the_papers(data: Path, tmp_path: Path) -> None:
    build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=tmp_path / "m",
            recipe=MemoryRecipe.chosen("pixels", pairing=CONCAT),
            split="train",
        )
    )
    manifest_path = tmp_path / "m" / "manifest.json"
    manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    del manifest["pairing"]
    manifest_path.write_text(json.dumps(manifest), encoding="utf-8")
    assert FailureMemory.load(tmp_path / "m").pairing == CONCAT
    manifest["pairing"] = "diff"
    manifest_path.write_text(json.dumps(manifest), encoding="utf-8")
    with pytest.raises(MemoryFormatError, match="'pairing' is 'diff', this version reads concat or change"):
        FailureMemory.load(tmp_path / "m")


def test_a_grown_memory_keeps_its_pairing(data: Path, tmp_path: Path) -> None:
    build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=tmp_path / "m",
            recipe=MemoryRecipe.chosen("pixels", pairing=CONCAT),
            split="train",
        )
    )
    with pytest.raises(SettingError, match="--pairing change differs from the memory"):
        build_memory(
            BuildMemoryConfig(
                data=DataSelection(data),
                out=tmp_path / "m",
                recipe=MemoryRecipe.chosen("pixels", pairing=CHANGE),
                split="test",
                add_to=True,
            )
        )
    grown, _ = build_memory(
        BuildMemoryConfig(
            data=DataSelection(data),
            out=tmp_path / "m",
            recipe=MemoryRecipe.chosen("pixels"),
            split="test",
            add_to=True,
        )
    )
    assert grown.pairing == CONCAT and FailureMemory.load(tmp_path / "m").pairing == CONCAT
