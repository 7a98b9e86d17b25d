"""`report.html`: an evaluation people read in any browser, self-contained (charts as inline SVG).

The same charts as the summary recording (rfr_viz.charts.evaluation), the evaluation's tables, and links
to the recordings written beside it (relative links, so the folder can be moved or shared whole).
"""

from __future__ import annotations

import html
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

from rfr_viz.charts.evaluation import evaluation_charts
from rfr_viz.charts.to_svg import chart_svg
from robofailring.atomic import write_text_atomic
from robofailring.detection.rules import PAPER, reported_default

REPORT_NAME: Final[str] = "report.html"
STYLE: Final[str] = """
body { font-family: system-ui, sans-serif; margin: 24px auto; max-width: 1440px; color: #222; }
h1 { font-size: 22px; } h2 { font-size: 18px; margin-top: 28px; border-bottom: 1px solid #ddd; }
.charts { display: flex; flex-wrap: wrap; gap: 12px; }
.charts svg { border: 1px solid #e2e2e2; border-radius: 4px; }
table { border-collapse: collapse; margin: 10px 0; font-size: 13px; }
th, td { border: 1px solid #d6d6d6; padding: 3px 8px; } th { background: #f3f3f3; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
code { background: #f3f3f3; padding: 0 3px; border-radius: 3px; }
details { margin: 8px 0; } summary { cursor: pointer; font-weight: 600; }
"""
_CODE = re.compile(r"`([^`]*)`")
_BOLD = re.compile(r"\*\*([^*]*)\*\*")
_ESCAPED = re.compile(r"\\([!-/:-@\[-`{-~])")  # Markdown's backslash escapes (`markdown_text` writes them)
_HIDDEN = re.compile("[\ue000-\ue07f]")  # an escaped character, held in the private use area meanwhile


def _hide(line: str) -> str:
    """The line with each escaped character out of the way of markup (`|`, `*`, `` ` ``), as one private character."""
    return _ESCAPED.sub(lambda match: chr(0xE000 + ord(match[1])), line)


def _inline(text: str) -> str:
    """A line or cell of `_hide`-den Markdown as HTML, its escaped characters as the text they are."""
    marked = _BOLD.sub(r"<b>\1</b>", _CODE.sub(r"<code>\1</code>", html.escape(text)))
    return _HIDDEN.sub(lambda match: html.escape(chr(ord(match[0]) - 0xE000)), marked)


def markdown_html(markdown: str) -> str:
    """The evaluation's markdown (headings, paragraphs, pipe tables, `code`, **bold**) as HTML."""
    out: list[str] = []
    table: list[list[str]] = []
    aligns: list[bool] = []

    def flush() -> None:
        if table:
            head, *rows = table
            out.append("<table><tr>" + "".join(f"<th>{_inline(c)}</th>" for c in head) + "</tr>")
            for row in rows:
                cells = [
                    f"<td{' class=num' if i < len(aligns) and aligns[i] else ''}>{_inline(c)}</td>"
                    for i, c in enumerate(row)
                ]
                out.append("<tr>" + "".join(cells) + "</tr>")
            out.append("</table>")
            table.clear()

    for line in map(_hide, markdown.splitlines()):
        if line.startswith("|"):
            cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
            if all(set(cell) <= set(":-") and cell for cell in cells):
                aligns[:] = [cell.endswith(":") for cell in cells]
            else:
                table.append(cells)
            continue
        flush()
        if line.startswith("## "):
            out.append(f"<h2>{_inline(line[3:])}</h2>")
        elif line.strip():
            out.append(f"<p>{_inline(line)}</p>")
    flush()
    return "\n".join(out)


def _links(recordings: Mapping[str, Path], folder: Path) -> str:
    if not recordings:
        return ""
    items = "".join(
        f'<li><a href="{html.escape(os.path.relpath(Path(path).resolve(), folder.resolve()))}">'
        f"{html.escape(label)}</a> <code>{html.escape(str(path))}</code></li>"
        for label, path in recordings.items()
    )
    return (
        "<h2>Recordings</h2><p>Open a recording with <code>rerun FILE</code> or "
        f"<code>robofailring open FILE</code> (paused at its alarm).</p><ul>{items}</ul>"
    )


def _review(evaluation: Mapping[str, Any], json_name: str) -> str:
    """Each rule's false alarms and misses, each named by its rule: first the rule a detector on the memory
    judges by by default (what `robofailring review` replays without --score), then the others (an
    evaluation written before every rule was reported: its paper rule's)."""
    rules: Mapping[str, Any] = evaluation.get("rules") or {
        PAPER.name: {kind: evaluation.get(kind) or [] for kind in ("false_alarms", "misses")}
    }
    default = reported_default(evaluation.get("rules") or {}).name
    lines = []
    for name in sorted(rules, key=lambda rule: rule != default):
        said = f"the {html.escape(name)} rule" + (" (the detector's default)" if name == default else "")
        score = "" if name == default else f" --score {html.escape(name)}"
        for kind, key, one in (("false-alarms", "false_alarms", "false alarm"), ("misses", "misses", "miss")):
            listed = [row if isinstance(row, str) else row["key"] for row in rules[name].get(key) or []]
            if not listed:
                continue
            what = one if len(listed) == 1 else kind.replace("-", " ")
            keys = ", ".join(html.escape(str(row)) for row in listed[:12])
            more = f" and {len(listed) - 12} more" if len(listed) > 12 else ""
            lines.append(
                f"<p><b>{len(listed)} {what}</b> of {said}: {keys}{more}. "
                + ("Replay it, paused" if len(listed) == 1 else "Replay them, each paused")
                + f" at the moment: <code>robofailring review {html.escape(json_name)} --data DATA --kind {kind}"
                f"{score}</code></p>"
            )
        if name == default and not lines:
            lines.append(f"<p>No false alarm and no miss of {said}.</p>")
    return "".join(lines)


def write_report(
    evaluations: Sequence[Mapping[str, Any]],
    out: Path,
    *,
    markdown: Sequence[str] = (),
    recordings: Mapping[str, Path] | None = None,
    title: str = "RoboFailRing evaluation",
) -> Path:
    """Write `report.html` at `out` (a file path) for the evaluation JSONs, with their `markdown` tables."""
    out = Path(out)
    sections = [f"<h1>{html.escape(title)}</h1>", _links(recordings or {}, out.parent)]
    for index, evaluation in enumerate(evaluations):
        name = str(evaluation.get("name", f"evaluation {index + 1}"))
        charts = (  # none for a cross-validation alone (`evaluate --folds` without a held-out evaluation)
            "\n".join(chart_svg(chart) for chart in evaluation_charts(evaluation))
            if "sweep" in evaluation
            else ""
        )
        text = markdown[index] if index < len(markdown) else ""
        if text.startswith("## "):  # its heading is the section's
            text = text.partition("\n")[2]
        tables = markdown_html(text)
        frames = evaluation.get("failure_frames")  # which failure memory (absent in older evaluations)
        pairing = evaluation.get("pairing")  # how it pairs frames (absent in older evaluations)
        memory = f", {html.escape(str(frames))} failure memory" if frames else ""
        memory += f", {html.escape(str(pairing))} pairing" if pairing else ""
        sections += [
            f"<h2>{html.escape(name)} — encoder <code>{html.escape(str(evaluation.get('encoder', '?')))}</code>"
            f"{memory}</h2>",
            f'<div class="charts">{charts}</div>' if charts else "",
            _review(evaluation, f"{name}.json"),
            f"<details open><summary>Tables</summary>{tables}</details>" if tables else "",
        ]
    page = (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>\n"
        + "\n".join(s for s in sections if s)
        + "\n</body></html>\n"
    )
    write_text_atomic(out, page, claim=True)
    return out
