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
from robofailring.outputs import MAX_STEM_BYTES, check_file_stem

PATHLIKE = st.lists(st.sampled_from(["..", ".", "/", "\\", "a", " ", "x.y", "\0", "é"]), max_size=6).map(
    "".join
)


@given(st.one_of(st.text(max_size=12), st.text(min_size=195, max_size=210), PATHLIKE))
@example("../notes")
@example("")
@example("..")
@example(".hidden")
@example("  ")
@example("a/../b")
@example("two\nlines")
@example("é" * 101)  # 202 bytes in UTF-8
def test_any_name_names_files_inside_out_or_is_refused_naming_it(name: str) -> None:
    out = Path("/srv/results/eval")
    try:
        checked = check_file_stem(name)
    except OutputError as error:
        long = len(name.encode("utf-8", "surrogatepass")) > MAX_STEM_BYTES
        assert (f"{name[:40]!r}… is" if long else repr(name)) in str(error) and "--name" in str(error)
        assert "\n" not in str(error)  # one `error:` line
        return
    assert checked == name and name.isprintable() and len(name.encode()) <= MAX_STEM_BYTES
    for suffix in (".json", ".md", ".rrd"):
        written = Path(os.path.normpath(out / f"{name}{suffix}"))
        assert written.parent == out and not written.name.startswith(".")


@pytest.mark.parametrize("name", ["evaluation", "in-distribution", "run 2", "α=0.05", "v1.2"])
def test_plain_names_are_kept(name: str) -> None:
    assert check_file_stem(name) == name
