"""Every figure the pages cite can be traced: a paragraph that points at one committed bench output
(`bench_*.txt`) quotes recall / FPR (/ T_s) figures that output has, every output is listed on the
benchmarks page, and every page that cites a timing has a row in its "Where each figure comes from"."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
BENCHMARKS = DOCS / "benchmarks.md"
# a measured duration or speed ratio in prose: "28 ms", "46-51 s", "26 + 22 min", "3.61× faster"
TIMING = re.compile(
    r"(?<![\w.])\d[\d.,]*(?:[–-]\d[\d.,]*)?\s?(?:ms|s|min|minutes|seconds)\b|\d[\d.]*×\s(?:faster|slower)"
    r"|seconds a frame"
)
# durations that are settings, not measurements
SETTINGS = {
    "vlm.md": "a request's timeout and the waits between retries",
    "environment.md": "how often a progress line is printed",
}
FIGURES = re.compile(r"(?<![\d.])(\d+\.\d) / (\d+\.\d)(?: / (\d+\.\d) %)?(?![\d.])")


def _runs(output: str) -> set[tuple[float, ...]]:
    """Every two and three consecutive numeric cells of the output's Markdown table rows."""
    found: set[tuple[float, ...]] = set()
    for line in output.splitlines():
        cells = [float(c) for c in re.findall(r"(?<=\|)\s*(-?\d+\.\d+)\s*(?=\|)", line)]
        found |= {tuple(cells[i : i + 2]) for i in range(len(cells) - 1)}
        found |= {tuple(cells[i : i + 3]) for i in range(len(cells) - 2)}
    return found


def _paragraphs_citing_one_output() -> list[tuple[str, str, str]]:
    """(page, output, text) of each paragraph citing exactly one bench output, with the table after it."""
    cited = []
    for page in sorted(DOCS.glob("*.md")):
        blocks = re.split(r"\n\s*\n", page.read_text())
        for i, paragraph in enumerate(blocks):
            outputs = sorted(set(re.findall(r"\((bench_\w+\.txt)\)", paragraph)))
            following = blocks[i + 1] if i + 1 < len(blocks) else ""
            table = following if following.lstrip().startswith("|") else ""
            if len(outputs) == 1:
                cited.append((page.name, outputs[0], f"{paragraph}\n{table}"))
    return cited


def test_quoted_figures_are_in_the_output_cited_beside_them() -> None:
    cited = _paragraphs_citing_one_output()
    checked, wrong = 0, []
    for page, output, text in cited:
        runs = _runs((DOCS / output).read_text())
        for figure in FIGURES.findall(text):
            numbers = tuple(float(n) for n in figure if n)
            checked += 1
            if numbers not in runs:
                wrong.append((page, output, " / ".join(n for n in figure if n)))
    assert checked > 50  # the figures were found
    assert wrong == []


def test_every_committed_output_is_listed_on_the_benchmarks_page() -> None:
    listed = BENCHMARKS.read_text().partition("## Full outputs")[2]
    assert sorted(p.name for p in DOCS.glob("bench_*.txt") if f"({p.name})" not in listed) == []


def test_every_page_citing_a_timing_has_a_row_saying_where_it_comes_from() -> None:
    table = BENCHMARKS.read_text().partition("## Where each figure comes from")[2].partition("\n## ")[0]
    rows = [line.split(" | ") for line in table.splitlines() if line.startswith("| ") and " | " in line]
    named = {page for row in rows[1:] for page in re.findall(r"\]\(([\w-]+\.md)", row[1])}
    timed = {}
    for page in sorted(DOCS.glob("*.md")):
        prose = page.read_text().partition("<!-- cli-reference")[0]  # the generated reference: --help's words
        found = TIMING.findall(prose)
        if found and page.name not in ("benchmarks.md", *SETTINGS):
            timed[page.name] = found[:3]
    assert len(timed) > 10  # the timings were found
    assert {page: found for page, found in timed.items() if page not in named} == {}
