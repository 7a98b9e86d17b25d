"""`triage.html`: the triage ranking for a browser, self-contained (thumbnails inline), in the report's style."""

from __future__ import annotations

import base64
import html
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Final

from rfr_viz.charts.report_html import STYLE
from robofailring.atomic import write_text_atomic
from robofailring.triage.scoring import EpisodeScore

TRIAGE_HTML: Final[str] = "triage.html"
_EXTRA_STYLE: Final[str] = (
    "img.thumb { height: 72px; image-rendering: auto; } td code { white-space: nowrap; }"
)


def _thumbnail(jpeg: bytes | None) -> str:
    if jpeg is None:
        return ""
    return (
        f'<img class="thumb" alt="peak frame" src="data:image/jpeg;base64,{base64.b64encode(jpeg).decode()}">'
    )


def _row(score: EpisodeScore, jpeg: bytes | None, command: str) -> str:
    cells = [
        f"<td class=num>{score.rank}</td>",
        f"<td>{_thumbnail(jpeg)}</td>",
        f"<td>{html.escape(score.task)}</td>",
        f"<td>{html.escape(score.episode)}</td>",
        f"<td class=num>{score.rank_score:.3f}</td>" if score.scored else "<td>not scored</td>",
        f"<td class=num>{score.frame}</td><td>{html.escape(score.view)}</td>"
        if score.scored
        else "<td></td><td></td>",
        f"<td>{html.escape(score.mode)}</td>",
        f"<td><code>{html.escape(score.failure_symbol)}</code> {html.escape(score.failure_description)}</td>"
        if score.failure_symbol
        else "<td></td>",
        f"<td>{html.escape(score.normal_episode)} frame {score.normal_frame}</td>"
        if score.normal_episode
        else "<td></td>",
        f"<td><code>{html.escape(command)}</code></td>",
    ]
    return "<tr>" + "".join(cells) + "</tr>"


def write_triage_page(
    ranked: Sequence[EpisodeScore],
    out: Path,
    *,
    thumbnails: Mapping[str, bytes],
    open_commands: Mapping[str, str],
    notes: Sequence[str] = (),
    files: Mapping[str, Path] | None = None,
) -> Path:
    """Write `triage.html` at `out`: the notes, links to `files` (label: path) and the ranked table."""
    out = Path(out)
    links = "".join(
        f'<li><a href="{html.escape(os.path.relpath(Path(p).resolve(), out.parent.resolve()))}">{html.escape(label)}</a></li>'
        for label, p in (files or {}).items()
    )
    head = (
        "<tr><th>rank</th><th>peak frame</th><th>task</th><th>episode</th><th>score</th><th>frame</th>"
        "<th>view</th><th>reference</th><th>nearest failure</th><th>nearest normal frame</th><th>open at its peak</th></tr>"
    )
    rows = "\n".join(_row(s, thumbnails.get(s.key), open_commands.get(s.key, "")) for s in ranked)
    page = (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>RoboFailRing triage</title>'
        f"<style>{STYLE}{_EXTRA_STYLE}</style></head><body>\n<h1>Triage: {len(ranked)} episodes, least normal first</h1>\n"
        + "".join(f"<p>{html.escape(note)}</p>" for note in notes)
        + (f"<ul>{links}</ul>" if links else "")
        + "<p>The first episodes have a replay that opens at their peak (<code>--replays N</code>, "
        "<code>-1</code> for every episode). "
        "Fill <code>outcome</code> (and <code>symbol</code>, <code>description</code>) in triage.csv, then "
        "<code>robofailring build-memory DATA --labels triage.csv --out MEMORY</code> and triage again with "
        "<code>--memory MEMORY</code>.</p>" + f"<table>{head}\n{rows}</table>\n</body></html>\n"
    )
    write_text_atomic(out, page, claim=True)
    return out
