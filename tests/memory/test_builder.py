"""The memory builder: one call gives the complete memory, evaluate's memory says where it came from,
saving changes nothing, and a bad JSONL row is named by file and line."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from synthetic import write_aha_dataset, write_project_dataset

from robofailring import CachedEncoder, FailureMemory, load_dataset, load_encoder
from robofailring.data.selection import DataSelection
from robofailring.encoders import portable_spec
from robofailring.encoders.base import BLANK_REASON
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import MemoryFormatError
from robofailring.evaluation.job import EvaluateConfig, build_training_memory
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.folder import ENTRIES, MANIFEST
from robofailring.memory.format import read_jsonl
from robofailring.memory.recipe import MemoryRecipe
from robofailring.memory.success import RUNS

PROVENANCE_KEYS = ("source", "layout", "encoder_spec", "split", "data_root", "skipped_inputs")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A project dataset with a file and a folder its manifest does not list (both skipped inputs)."""
    root = write_project_dataset(tmp_path_factory.mktemp("builder") / "data", tasks=("pick_cube",))
    (root / "notes.txt").write_text("not data", encoding="utf-8")
    (root / "stray").mkdir()
    return root


def _skipped(root: Path) -> list[dict[str, str]]:
    reason = "not listed in manifest.json"
    return [
        {"path": str(root / "notes.txt"), "reason": reason},
        {"path": str(root / "stray"), "reason": reason},
    ]


def test_one_call_builds_the_complete_memory(dataset: Path, encoder: CachedEncoder) -> None:
    loaded = load_dataset(dataset)
    train = loaded.select(split="train")
    provenance = Provenance(
        data=dataset, encoder="pixels", layout=loaded.layout, split="train", skipped_inputs=loaded.skipped
    )
    memory, stats = build_memories(train, encoder, provenance=provenance)

    failures = [t for t in train if t.is_failure]
    successes = [t for t in train if not t.is_failure]
    # dense by default: frames 1-5 of every failure view (no onset recorded; these frames all differ)
    assert len(memory) == stats.entries == sum(len(t.views) * (t.length - 1) for t in failures) > 0
    assert stats.views == sum(len(t.views) for t in failures)
    assert memory.data_root == dataset.resolve()
    manifest = memory.manifest
    assert manifest.source == manifest.data_root == str(dataset.resolve())
    assert (manifest.layout, manifest.split) == ("project", "train")
    assert manifest.encoder_spec == portable_spec("pixels") and manifest.encoder == encoder.identity
    assert manifest.skipped_inputs == _skipped(dataset) and stats.skipped_inputs == loaded.skipped
    assert manifest.failures == len(failures) and manifest.ignored_non_failures == len(successes)
    assert manifest.created is not None
    assert memory.successes is not None  # attached at construction
    assert memory.successes.success_runs == sum(len(t.views) for t in successes)
    assert memory.successes.tasks == memory.tasks == ["pick_cube"]


def test_no_success_run_or_none_asked_gives_the_paper_memory(tmp_path: Path, encoder: CachedEncoder) -> None:
    aha = write_aha_dataset(tmp_path / "aha", tasks=("pick_cube",), episodes=1)  # failures only
    provenance = Provenance(data=aha, encoder="pixels", layout="aha")
    memory, _ = build_memories(
        list(load_dataset(aha)), encoder, provenance=provenance, recipe=MemoryRecipe(failure_frames="end")
    )
    assert memory.successes is None and len(memory) == 9 and memory.manifest.failure_frames == "end"

    project = write_project_dataset(tmp_path / "project", tasks=("pick_cube",), episodes=2)
    memory, _ = build_memories(
        list(load_dataset(project)),
        encoder,
        provenance=Provenance(data=project, encoder="pixels"),
        successes=False,
    )
    assert memory.successes is None and memory.manifest.successes is None


def test_evaluate_and_build_memory_record_the_same_provenance(dataset: Path, tmp_path: Path) -> None:
    """evaluate's memory now carries the data root, layout and skipped inputs, as build-memory's does."""
    cache = tmp_path / "cache"
    evaluated, _ = build_training_memory(
        EvaluateConfig(
            data=DataSelection(dataset), placement=EncoderPlacement(cache_dir=cache), out=tmp_path / "eval"
        )
    )
    build_memory(
        BuildMemoryConfig(
            data=DataSelection(dataset),
            out=tmp_path / "built",
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=cache),
            split="train",
        )
    )
    written = {
        name: json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
        for name, folder in (("evaluate", evaluated), ("build-memory", tmp_path / "built"))
    }
    expected = {
        "source": str(dataset.resolve()),
        "layout": "project",
        "encoder_spec": portable_spec("pixels"),
        "split": "train",
        "data_root": str(dataset.resolve()),
        "skipped_inputs": _skipped(dataset),
    }
    for manifest in written.values():
        assert {key: manifest.get(key) for key in PROVENANCE_KEYS} == expected
    same = ("count", "tasks", "symbols", "successes", "failures", "dim")
    assert {k: written["evaluate"][k] for k in same} == {k: written["build-memory"][k] for k in same}
    assert FailureMemory.load(evaluated).data_root == dataset.resolve()


def _state(memory: FailureMemory) -> tuple[Any, ...]:
    successes = memory.successes
    return (
        memory.manifest.to_dict(),
        list(memory.entries),
        memory.data_root,
        memory.vectors.copy(),
        None if successes is None else (list(successes.runs), successes.manifest()),
    )


def _assert_same(before: tuple[Any, ...], after: tuple[Any, ...]) -> None:
    assert after[:3] == before[:3]
    assert (after[3] == before[3]).all()
    assert after[4] == before[4]


@pytest.mark.parametrize("complete", [False, True])
def test_save_does_not_change_the_memory(
    complete: bool, dataset: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    trajectories = load_dataset(dataset).select(split="train")
    if complete:
        memory, _ = build_memories(
            trajectories, encoder, provenance=Provenance(data=dataset, encoder="pixels")
        )
    else:  # no data root given: save stores references under their common folder, and records it
        memory, _ = FailureMemory.build(trajectories, encoder)
    before = _state(memory)
    memory.save(tmp_path / "memory")
    _assert_same(before, _state(memory))
    assert memory.data_root == (dataset.resolve() if complete else None)
    written = json.loads((tmp_path / "memory" / MANIFEST).read_text(encoding="utf-8"))
    assert written["data_root"] == str(dataset.resolve())  # the deepest folder of every image: the data root
    assert memory.manifest.count == (
        0 if not complete else memory.manifest.count
    )  # counts are written, not set
    assert written["count"] == len(memory) and written["created"] == memory.manifest.created
    memory.save(tmp_path / "again")
    assert json.loads((tmp_path / "again" / MANIFEST).read_text(encoding="utf-8")) == written
    first = json.loads((tmp_path / "memory" / ENTRIES).read_text(encoding="utf-8").splitlines()[0])
    assert not first["start"].startswith("/") and first["start"].endswith(".png")  # relative to the root
    loaded = FailureMemory.load(tmp_path / "memory")
    assert loaded.entries == memory.entries and loaded.manifest.to_dict() == written


def test_the_jsonl_reader_names_the_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "rows.jsonl"
    path.write_text('{"a": 1}\n\n{"b": 2}\n{oops\n', encoding="utf-8")
    with pytest.raises(MemoryFormatError, match=rf"^{re.escape(str(path))}:4 is not valid JSON"):
        read_jsonl(path, lambda row: row, what="row")
    with pytest.raises(
        MemoryFormatError, match=rf"^{re.escape(str(path))}:3: bad row \('a'\)"
    ):  # a KeyError of the parser
        read_jsonl(path, lambda row: row["a"], what="row")
    path.write_text('{"a": 1}\n\n{"a": 2}\n', encoding="utf-8")
    assert read_jsonl(path, lambda row: row["a"], what="row") == [1, 2]
    with pytest.raises(MemoryFormatError, match=r"cannot read .*missing\.jsonl"):
        read_jsonl(tmp_path / "missing.jsonl", lambda row: row, what="row")


def test_both_memories_name_the_file_and_line_of_a_bad_row(
    dataset: Path, encoder: CachedEncoder, tmp_path: Path
) -> None:
    memory, _ = build_memories(
        load_dataset(dataset).select(split="train"),
        encoder,
        provenance=Provenance(data=dataset, encoder="pixels"),
    )
    folder = memory.save(tmp_path / "memory")
    for name, broken, expected in (
        (ENTRIES, {"task": "pick_cube"}, "an entry is an object with task, symbol"),
        (
            RUNS,
            {"task": "pick_cube", "episode": "e", "view": "front"},
            r"bad success run \('frames' must be a list",
        ),
    ):
        original = (folder / name).read_text(encoding="utf-8")
        lines = original.splitlines()
        lines[1] = json.dumps(broken)
        (folder / name).write_text("\n".join(lines) + "\n", encoding="utf-8")
        with pytest.raises(MemoryFormatError, match=rf"{re.escape(str(folder / name))}:2: {expected}"):
            FailureMemory.load(folder)
        (folder / name).write_text(original, encoding="utf-8")
    assert FailureMemory.load(folder).entries == memory.entries


class _NoNumberFor:
    """The pixels encoder, but an embedding of NaN for the images given (a network that overflowed on them)."""

    def __init__(self, images: list[np.ndarray]) -> None:
        self._pixels = load_encoder("pixels")
        self._poisoned = {np.asarray(image).tobytes() for image in images}

    @property
    def identity(self) -> str:
        return "pixels-with-nan"

    @property
    def dim(self) -> int:
        return self._pixels.dim

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        rows = self._pixels.encode(images).copy()
        rows[[np.asarray(image).tobytes() in self._poisoned for image in images]] = np.nan
        return rows


def test_frames_the_encoder_gives_no_number_for_are_never_stored(tmp_path: Path) -> None:
    """An embedding that is not a number is no image to match (`encoders.base.unusable`), as a blank frame is:
    neither memory stores it, and the build lists the frames it left out."""
    data = write_project_dataset(
        tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=8
    )
    train = load_dataset(data).select(split="train")
    failure = next(t for t in train if t.is_failure)
    success = next(t for t in train if not t.is_failure)
    poisoned = [failure.views["front"][t].load() for t in (4, 5)] + [success.views["wrist"][3].load()]
    encoder = CachedEncoder(_NoNumberFor(poisoned), cache_dir=tmp_path / "cache")
    memory, stats = build_memories(train, encoder, provenance=Provenance(data=data, encoder="pixels"))
    reasons = [skipped.reason for skipped in stats.skipped_inputs]
    assert f"pick_cube/{failure.episode} view front: frame(s) 4–5 of 8 are {BLANK_REASON}" in reasons
    assert any(reason.startswith(f"pick_cube/{success.episode} view wrist") for reason in reasons), reasons
    assert np.isfinite(memory.vectors).all()
    stored = {(entry.episode, entry.view, entry.frame) for entry in memory.entries}
    assert (failure.episode, "front", 6) in stored  # the view is in, without the two frames
    assert not stored & {(failure.episode, "front", 4), (failure.episode, "front", 5)}
    assert memory.successes is not None and memory.successes.vectors is not None
    assert np.isfinite(memory.successes.vectors).all()
    (wrist,) = [run for run in memory.successes.runs if (run.episode, run.view) == (success.episode, "wrist")]
    assert 3 not in wrist.frame_numbers and wrist.frame_numbers
