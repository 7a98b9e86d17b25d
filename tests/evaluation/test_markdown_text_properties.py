"""Text from the data in the evaluation's Markdown (`markdown_text`): any text stays one table cell and reads
back as itself, in a CommonMark renderer with GFM tables and in report.html's own reader."""

from __future__ import annotations

import html
import re

from environment import require_module
from hypothesis import example, given
from hypothesis import strategies as st

from rfr_viz.charts.report_html import markdown_html
from robofailring.evaluation.markdown import markdown_text

markdown_it = require_module("markdown_it", "pip install markdown-it-py (typer's rich brings it)")
RENDERER = markdown_it.MarkdownIt("commonmark").enable(["table", "strikethrough"])
# any printable text; not the private use area, where report.html holds escaped characters meanwhile
TEXT = st.text(st.characters(blacklist_categories=("Cs", "Cc", "Co")), max_size=40)


def _cells(rendered: str) -> list[str]:
    return [html.unescape(cell) for cell in re.findall(r"<td[^>]*>(.*?)</td>", rendered, re.DOTALL)]


@given(TEXT, st.booleans())
@example("C:\\data\\*run*", True)
@example("a | b <i>", True)
def test_any_text_is_one_cell_that_reads_back_as_itself(text: str, code: bool) -> None:
    flat = " ".join(text.split())
    table = f"| name | n |\n|---|---:|\n| {markdown_text(text, code=code)} | 1 |\n"
    rendered = RENDERER.render(table)
    cell = re.sub(r"</?code>", "", _cells(rendered)[0]) if code else _cells(rendered)[0]
    assert (cell, _cells(rendered)[1:]) == (flat, ["1"])
    assert "<" not in re.sub(r"</?(code|td|tr|th|table|thead|tbody)[^>]*>", "", rendered).replace("&lt;", "")
    ours = re.sub(r"</?code>", "", markdown_html(table))
    assert _cells(ours) == [flat, "1"]


def test_markup_in_a_name_is_escaped_and_plain_names_are_left_as_they_are() -> None:
    assert markdown_text("pick|cube <b>x</b>") == r"pick\|cube \<b\>x\</b\>"
    assert markdown_text("pick_cube_episode3") == "pick_cube_episode3"
    assert markdown_text("grasp_wp2", code=True) == "`grasp_wp2`"
    assert markdown_text("a`b", code=True) == r"a\`b"
