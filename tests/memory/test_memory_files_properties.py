"""A memory's files are input too (copied, hand-edited, half-synced): `manifest.json`, `entries.jsonl` and
`success_runs.jsonl` with any content load or raise MemoryFormatError naming the file, never another error."""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from crafted import GIB_OF_FLOATS, declare_in_index, nested_json
from fault_helpers import cli
from hypothesis import assume, example, given
from hypothesis import strategies as st
from synthetic import write_project_dataset

from robofailring.errors import MemoryFormatError
from robofailring.memory.failure import FailureMemory
from robofailring.memory.folder import ENTRIES, INDEX, MANIFEST
from robofailring.memory.format import ENTRY_FIELDS, parse_entry, read_jsonl
from robofailring.memory.manifest import MemoryManifest
from robofailring.memory.success import RUNS

JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=8,
)
MANIFEST_KEYS = (
    "encoder",
    "dim",
    "count",
    "format_version",
    "tasks",
    "views",
    "successes",
    "calibration",
    "data_root",
    "failure_frames",
    "failure_step",
)
RUN_KEYS = ("task", "episode", "view", "frames", "kind", "frame_numbers")


def _objects(keys: tuple[str, ...]) -> st.SearchStrategy[dict[str, Any]]:
    """Objects with some (or all) of `keys`, their values of any JSON type."""
    value = JSON | st.sampled_from([0, 2, 0.5, "pixels", "a/b", "end", "dense", ["x"], ["1", "x"], {}])
    return st.dictionaries(st.sampled_from(keys), value) | st.fixed_dictionaries(dict.fromkeys(keys, value))


def _lines(keys: tuple[str, ...]) -> st.SearchStrategy[str]:
    return st.one_of(st.text(max_size=40), JSON.map(json.dumps), _objects(keys).map(json.dumps))


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real memory with a success memory, built by the CLI."""
    root = tmp_path_factory.mktemp("memory-files")
    data = write_project_dataset(
        root / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=3
    )
    result = cli(
        "build-memory", data, "--out", root / "memory", "--split", "train", "--cache-dir", root / "cache"
    )
    assert result.exit_code == 0, result.output
    assert (root / "memory" / RUNS).is_file()
    return root / "memory"


@pytest.fixture(scope="module")
def scratch(saved: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    copy = tmp_path_factory.mktemp("scratch") / "memory"
    shutil.copytree(saved, copy)
    yield copy


def _load_with(memory: Path, saved: Path, name: str, content: bytes) -> None:
    """Load `memory` with file `name` holding `content` (the other files as saved)."""
    original = (saved / name).read_bytes()
    (memory / name).write_bytes(content)
    try:
        FailureMemory.load(memory)
    except MemoryFormatError as error:
        assert str(memory) in str(error)
    finally:
        (memory / name).write_bytes(original)


@given(st.one_of(JSON, _objects(MANIFEST_KEYS)))
def test_any_manifest_value_parses_or_raises_naming_the_file(value: Any) -> None:
    path = Path("/m/manifest.json")
    try:
        manifest = MemoryManifest.parse(value, path)
    except MemoryFormatError as error:
        assert str(path) in str(error)
    else:
        assert MemoryManifest.parse(manifest.to_dict(), path).to_dict() == manifest.to_dict()


@given(st.one_of(st.binary(max_size=100), _objects(MANIFEST_KEYS).map(lambda v: json.dumps(v).encode())))
def test_any_manifest_file_loads_or_raises_naming_it(scratch: Path, saved: Path, content: bytes) -> None:
    _load_with(scratch, saved, MANIFEST, content)


@given(
    st.integers(min_value=1, max_value=200_000),
    st.sampled_from(["[", "{"]),
    st.sampled_from([MANIFEST, ENTRIES]),
)
def test_a_memory_file_nested_to_any_depth_loads_or_raises_naming_it(
    scratch: Path, saved: Path, depth: int, opener: str, name: str
) -> None:
    _load_with(scratch, saved, name, nested_json(depth, opener=opener).encode())


@given(_lines(ENTRY_FIELDS))
def test_any_entries_line_parses_or_raises_naming_the_file_and_line(line: str) -> None:
    assume(not any(character in line for character in "\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / ENTRIES
        path.write_text("\n" * 6 + line + "\n", encoding="utf-8")  # the line is line 7
        try:
            rows = read_jsonl(path, parse_entry, what="entry")
        except MemoryFormatError as error:
            assert f"{path}:7" in str(error)
        else:
            assert all(isinstance(row[key], str) for row in rows for key in ENTRY_FIELDS)


MOMENT = st.one_of(JSON, st.integers(min_value=-3, max_value=12))


@given(
    st.fixed_dictionaries(dict.fromkeys(ENTRY_FIELDS, st.just("pick_cube"))).map(
        lambda row: row | {"symbol": "grasp_wp2"}
    ),
    st.dictionaries(st.sampled_from(["frame", "length"]), MOMENT),
)
def test_any_frame_and_length_parse_to_a_moment_or_raise_naming_the_line(
    row: dict[str, Any], moment: dict[str, Any]
) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / ENTRIES
        path.write_text("\n" + json.dumps(row | moment) + "\n", encoding="utf-8")
        try:
            (parsed,) = read_jsonl(path, parse_entry, what="entry")
        except MemoryFormatError as error:
            assert f"{path}:2: " in str(error) and ("'frame'" in str(error) or "'length'" in str(error))
        else:
            frame, length = parsed["frame"], parsed["length"]
            assert (frame, length) == (moment.get("frame"), moment.get("length"))
            assert (frame is None and length is None) or (
                type(frame) is int and type(length) is int and 0 <= frame < length
            )


@given(st.one_of(st.binary(max_size=100), _lines(ENTRY_FIELDS).map(str.encode)))
def test_any_entries_file_loads_or_raises_naming_it(scratch: Path, saved: Path, content: bytes) -> None:
    _load_with(scratch, saved, ENTRIES, content)


@given(st.one_of(st.binary(max_size=100), _lines(RUN_KEYS).map(str.encode)), st.booleans())
def test_any_success_runs_file_loads_or_raises_naming_it(
    scratch: Path, saved: Path, content: bytes, replace_first: bool
) -> None:
    lines = (saved / RUNS).read_bytes().splitlines(keepends=True)
    fuzzed = content + b"\n" + b"".join(lines[1:]) if replace_first else content
    _load_with(scratch, saved, RUNS, fuzzed)


# Declared sizes: near the true one, or past this machine's memory (a regression then fails to allocate,
# it never fills the RAM)
DECLARED = st.integers(0, 2**16) | st.integers(32 * GIB_OF_FLOATS, 2**63 - 1)


@given(st.sampled_from([INDEX, "success.0.faiss"]), st.none() | DECLARED, st.none() | DECLARED)
@example(INDEX, None, 50 * GIB_OF_FLOATS)  # issue 45, item 6: std::bad_alloc, a MemoryError traceback
def test_an_index_declaring_any_entries_or_vectors_loads_or_raises_naming_it(
    scratch: Path, saved: Path, name: str, entries: int | None, floats: int | None
) -> None:
    with tempfile.TemporaryDirectory() as folder:
        content = declare_in_index(Path(shutil.copy(saved / name, folder)), entries=entries, floats=floats)
        _load_with(scratch, saved, name, content.read_bytes())
