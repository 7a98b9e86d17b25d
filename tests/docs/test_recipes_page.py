"""docs/recipes.md's tables name every field of the values the command line's groups make, with the default
the class has, and every fusion the thresholds take (issue 53: `band_scope`, `signal_features`,
`signal_start_weight` and `per-modality` were missing)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

import robofailring as rfr
from robofailring.calibration.fusions import FUSIONS
from robofailring.memory.signals.derived import SignalFeatures

PAGE = Path(__file__).resolve().parents[2] / "docs" / "recipes.md"


def _rows() -> dict[str, tuple[str, str]]:
    """`field` → (default, what it chooses) of the page's field tables."""
    found = re.findall(r"^\| `(\w+)` \| ([^|]*) \| (.*) \|$", PAGE.read_text(), re.MULTILINE)
    return {name: (default.strip(), what) for name, default, what in found}


@pytest.mark.parametrize(
    "value", [rfr.DataSelection, rfr.MemoryRecipe, rfr.ThresholdPolicy], ids=lambda v: v.__name__
)
def test_every_field_has_a_row(value: type) -> None:
    rows = _rows()
    fields = [
        f.name for f in dataclasses.fields(value) if f.name != "given"
    ]  # `given`: bookkeeping, not a setting
    assert [name for name in fields if name not in rows] == []


@pytest.mark.parametrize("value", [rfr.MemoryRecipe(), rfr.ThresholdPolicy()], ids=lambda v: type(v).__name__)
def test_each_rows_default_is_the_classs(value: object) -> None:
    rows = _rows()
    wrong = {}
    for field in dataclasses.fields(value):  # type: ignore[arg-type]
        default = getattr(value, field.name)
        if field.name in rows and isinstance(default, str | float | SignalFeatures):  # features: their text
            said = f"`{default:g}`" if isinstance(default, float) else f"`{default}`"
            if rows[field.name][0] != said:
                wrong[field.name] = (rows[field.name][0], said)
    assert wrong == {}


def test_the_fusion_row_names_every_fusion() -> None:
    what = _rows()["fusion"][1]
    assert [fusion for fusion in FUSIONS if f"`{fusion}`" not in what] == []
    assert len(FUSIONS) == 3
