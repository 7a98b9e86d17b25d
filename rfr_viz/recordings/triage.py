"""`triage.rrd`: every episode of a triaged dataset in one recording, to browse them all at once.

Every episode's score curve in one plot (the frame timeline; the ranking's top share drawn in red),
each episode's frame at its peak with what triage says about it (`/triage/episodes/<rank>`, the
first ones side by side in the layout), each episode's ranking score in rank order, and the ranked
table with the command that opens each episode's replay at its peak.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Final

import numpy as np

from rfr_viz.paths import FRAME, TRIAGE_CURVES, TRIAGE_RANKING, TRIAGE_SCORES, triage_curve, triage_episode
from rfr_viz.recordings.blueprint import NO_LEGEND
from rfr_viz.recordings.replay import open_recording
from rfr_viz.styles import DELTA_COLOUR, STATE_COLOUR
from robofailring.extras import needs_extra
from robofailring.triage.ranking import TOP_SHARE
from robofailring.triage.scoring import EpisodeScore

with needs_extra("viz"):
    import rerun as rr
    import rerun.blueprint as rrb

SHOWN: Final[int] = 8  # episodes whose peak frames the layout shows side by side (the others: in the tree)


def episode_text(score: EpisodeScore, open_command: str) -> str:
    """What triage says about one episode, as markdown."""
    lines = [
        f"### #{score.rank} {score.task}/{score.episode}",
        f"score **{score.rank_score:.3f}** (peak {score.rule} {score.peak:.4f} at frame {score.frame}, "
        f"view `{score.view}`; reference: {score.mode})"
        if score.scored
        else "not scored: " + "; ".join(s.reason for s in score.skipped),
    ]
    if score.failure_symbol:
        lines.append(f"nearest failure: `{score.failure_symbol}` — {score.failure_description}")
    if score.normal_episode:
        lines.append(f"nearest normal frame: {score.normal_episode} frame {score.normal_frame}")
    if open_command:
        lines.append(f"open it at its peak: `{open_command}`")
    return "\n\n".join(lines)


def ranking_markdown(ranked: Sequence[EpisodeScore], notes: Sequence[str]) -> str:
    """The ranked table (and the notes on how the tasks were judged) as markdown."""
    head = (
        "| rank | task | episode | score | frame | view | nearest failure |\n|---:|---|---|---:|---:|---|---|"
    )
    rows = [
        f"| {s.rank} | {s.task} | {s.episode} | {s.rank_score:.3f} | {s.frame} | {s.view} | {s.failure_symbol} |"
        if s.scored
        else f"| {s.rank} | {s.task} | {s.episode} | — | — | — | not scored |"
        for s in ranked
    ]
    return "\n".join(["## Triage", *(f"- {note}" for note in notes), "", head, *rows])


def triage_blueprint(ranked: Sequence[EpisodeScore]) -> rrb.Blueprint:
    """Curves and rank order on the left, the first episodes' peak frames and the table on the right."""
    shown = [s for s in ranked[:SHOWN]]
    peaks = rrb.Grid(
        *(
            rrb.Spatial2DView(origin=f"{triage_episode(s.rank)}/peak", name=f"#{s.rank} {s.episode}")
            for s in shown
        ),
        grid_columns=4,
        name="peak frames",
    )
    left = rrb.Vertical(
        rrb.TimeSeriesView(origin=TRIAGE_CURVES, name="score curves (every episode)", plot_legend=NO_LEGEND),
        rrb.BarChartView(origin=TRIAGE_SCORES, name="ranking score, in rank order"),
        row_shares=[2, 1],
    )
    right = rrb.Vertical(
        peaks,
        rrb.Tabs(
            rrb.TextDocumentView(origin=TRIAGE_RANKING, name="ranking"),
            *(
                rrb.TextDocumentView(origin=f"{triage_episode(s.rank)}/info", name=f"#{s.rank}")
                for s in shown
            ),
        ),
        row_shares=[1, 1.2],
    )
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[1, 1.2]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline=FRAME),
    )


def record_triage(
    ranked: Sequence[EpisodeScore],
    *,
    out: Path,
    thumbnails: Mapping[str, bytes],
    open_commands: Mapping[str, str],
    notes: Sequence[str] = (),
) -> Path:
    """Write `triage.rrd` at `out`, atomically (`thumbnails` and `open_commands` by episode key)."""
    top = max(1, round(TOP_SHARE * len(ranked)))
    with open_recording(out, triage_blueprint(ranked), recording_id=None) as rec:
        rec.send_recording_name("triage")
        rec.log(
            TRIAGE_RANKING,
            rr.TextDocument(ranking_markdown(ranked, notes), media_type="text/markdown"),
            static=True,
        )
        values = np.asarray([s.rank_score if s.scored else 0.0 for s in ranked], dtype=np.float32)
        rec.log(TRIAGE_SCORES, rr.BarChart(values), static=True)
        for score in ranked:
            episode = triage_episode(score.rank)
            text = episode_text(score, open_commands.get(score.key, ""))
            rec.log(f"{episode}/info", rr.TextDocument(text, media_type="text/markdown"), static=True)
            jpeg = thumbnails.get(score.key)
            if jpeg is not None:
                rec.log(
                    f"{episode}/peak", rr.EncodedImage(contents=jpeg, media_type="image/jpeg"), static=True
                )
            frames = np.flatnonzero(np.isfinite(score.curve))
            if not frames.size:
                continue
            curve = triage_curve(score.rank)
            colour = DELTA_COLOUR if score.rank <= top else STATE_COLOUR
            rec.log(
                curve,
                rr.SeriesLines(colors=[colour], widths=[1.0], names=[f"#{score.rank} {score.key}"]),
                static=True,
            )
            rec.send_columns(
                curve,
                indexes=[rr.TimeColumn(FRAME, sequence=frames)],
                columns=rr.Scalars.columns(scalars=score.curve[frames].astype(np.float64)),
            )
    return Path(out)
