"""Triage: every episode of a dataset nobody labelled, scored and ranked by how unlike normal runs it looks.

`run_triage(TriageConfig(...))` picks the reference each task is judged against (`reference`: a
memory, known-good runs, or the task's other episodes), scores every episode once, streaming
(`scoring`), ranks them (`ranking`) and gives the rows of the labels CSV a person fills in
(`table`); `rfr_viz.jobs.triage` writes them with the recording and the HTML page.
"""

from __future__ import annotations

from robofailring.triage.job import TriageConfig, TriageResult, run_triage
from robofailring.triage.ranking import RankingQuality, ranking_quality
from robofailring.triage.scoring import EpisodeScore

__all__ = ["EpisodeScore", "RankingQuality", "TriageConfig", "TriageResult", "ranking_quality", "run_triage"]
