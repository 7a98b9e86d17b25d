"""`evaluate --name` is user input that becomes file names (`<name>.json`, `.md`, `.rrd` in `--out`):
any text is either a name whose files lie directly in `--out`, visible, or an OutputError naming it
(issue 50, data loss: `../notes` replaced a file beside `--out`, `""` wrote dotfiles)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from robofailring.errors import OutputError
from robofailring.outputs import check_file_stem

PATHLIKE = st.lists(st.sampled_from(["..", ".", "/", "\\", "a", " ", "x.y", "\0", "é"]), max_size=6).map(
    "".join
)


@given(st.one_of(st.text(max_size=12), PATHLIKE))
@example("../notes")
@example("")
@example("..")
@example(".hidden")
@example("  ")
@example("a/../b")
def test_any_name_names_files_inside_out_or_is_refused_naming_it(name: str) -> None:
    out = Path("/srv/results/eval")
    try:
        checked = check_file_stem(name)
    except OutputError as error:
        assert repr(name) in str(error) and "--name" in str(error)
        return
    assert checked == name
    for suffix in (".json", ".md", ".rrd"):
        written = Path(os.path.normpath(out / f"{name}{suffix}"))
        assert written.parent == out and not written.name.startswith(".")


@pytest.mark.parametrize("name", ["evaluation", "in-distribution", "run 2", "α=0.05", "v1.2"])
def test_plain_names_are_kept(name: str) -> None:
    assert check_file_stem(name) == name
