"""The manifest's `signals` section read once into a typed value (issue 53 item 3): an older memory's section reads
as that version meant it and is written back as the same JSON, a damaged one is one MemoryFormatError naming the
manifest, and `--signal-features` is parsed once into `SignalFeatures`, whose text is what manifests keep."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robofailring.errors import MemoryFormatError
from robofailring.memory.manifest import MemoryManifest
from robofailring.memory.recipe import MemoryRecipe
from robofailring.memory.signals.derived import KINDS, NO_FEATURES, SignalFeatures
from robofailring.memory.signals.section import SignalSection
from robofailring.memory.signals.task import START_WEIGHT

PATH = Path("memory") / "manifest.json"


def _older() -> dict[str, Any]:
    """A manifest with a signal memory as a version before derived features and the start weight wrote it, with a
    key of a newer version at the top of the section and in its task."""
    return {
        "dim": 8,
        "encoder": "pixels",
        "count": 0,
        "signals": {
            "file": "signals.npz",
            "choice": "gripper_width,action:grip*",
            "tasks": {
                "pick_cube": {
                    "key": "t0",
                    "layout": {"state": [["gripper_width", ["width"]]], "action": [["action", ["gripper"]]]},
                    "failure_entries": 28,
                    "success_entries": 16,
                    "from_a_newer_version": [1, 2],
                }
            },
            "note": "kept",
        },
    }


def test_an_older_section_reads_as_its_version_meant_and_is_written_back_as_it_was() -> None:
    manifest = MemoryManifest.parse(_older(), PATH)
    section = manifest.signals
    assert isinstance(section, SignalSection)
    assert section.features == NO_FEATURES and section.start_weight == START_WEIGHT == 0.5
    assert section.choice == "gripper_width,action:grip*"
    task = section.tasks["pick_cube"]
    assert task.key == "t0" and task.entries == {"failure": 28, "success": 16} and task.selected is None
    assert task.layout.names == ["gripper_width", "action"] and task.layout.derived == ()
    assert manifest.to_dict() == _older()
    recipe = MemoryRecipe.of(manifest)
    assert str(recipe.signal_features) == "none" and recipe.signal_start_weight == 0.5
    assert recipe.signals == "gripper_width,action:grip*"


def test_an_empty_section_is_no_signal_memory_and_stays() -> None:
    older = _older() | {"signals": {}}
    manifest = MemoryManifest.parse(older, PATH)
    assert manifest.signals is None and manifest.to_dict() == older


@pytest.mark.parametrize(
    ("change", "phrase"),
    [
        (lambda s: s.update(features="jerk"), "--signal-features takes none or change, events"),
        (lambda s: s.update(features=3), "features 3 are not a string"),
        (lambda s: s.update(start_weight=-1), "must be a number from 0 to 100"),
        (lambda s: s.update(choice=""), "--signals takes auto, none"),
        (lambda s: s.pop("tasks"), "lacks 'tasks'"),
        (lambda s: s["tasks"]["pick_cube"].update(key=5), "task 'pick_cube' has no key"),
        (lambda s: s["tasks"]["pick_cube"].update(failure_entries=-1), "failure_entries -1 is not a count"),
        (
            lambda s: s["tasks"]["pick_cube"].update(selection={"elements": True}),
            "keeps True signal elements",
        ),
        (lambda s: s["tasks"]["pick_cube"].update(layout={"state": 1}), "bad signal layout"),
        (lambda s: s["tasks"]["pick_cube"]["layout"].update(derived=["jerk"]), "bad signal layout"),
    ],
)
def test_a_damaged_section_is_one_error_naming_the_manifest(change: Any, phrase: str) -> None:
    damaged = copy.deepcopy(_older())
    change(damaged["signals"])
    with pytest.raises(MemoryFormatError, match=str(PATH)) as raised:
        MemoryManifest.parse(damaged, PATH)
    assert phrase in str(raised.value)


@given(st.lists(st.sampled_from([*KINDS, "none", ",", " ", "x"]), max_size=8).map("".join))
def test_any_features_text_parses_or_is_refused_and_keeps_its_text(text: str) -> None:
    try:
        features = SignalFeatures.parse(text)
    except ValueError as error:
        assert "--signal-features takes none or change, events" in str(error)
        return
    assert str(features) == text and set(features.kinds) <= set(KINDS)
    assert list(features.kinds) == [kind for kind in KINDS if kind in features.kinds]  # in KINDS' order
    assert SignalFeatures.of_kinds(features.kinds) == features  # the same kinds, whatever text gave them
