"""Old rfr_viz module paths still import for one release, each with a DeprecationWarning (robofailring._moved)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from robofailring._moved import install

MOVED: Final[Mapping[str, str]] = dict(
    {
        "rfr_viz._images": "rfr_viz.panels.images",
        "rfr_viz.blueprint": "rfr_viz.recordings.blueprint rfr_viz.panels.map",
        "rfr_viz.camera_video": "rfr_viz.panels.camera_video rfr_viz.panels.cameras rfr_viz.codecs",
        "rfr_viz.chart_rerun": "rfr_viz.charts.to_rerun",
        "rfr_viz.chart_svg": "rfr_viz.charts.to_svg",
        "rfr_viz.cli_jobs": "rfr_viz.cli.jobs",
        "rfr_viz.cli_live": "rfr_viz.cli.live",
        "rfr_viz.cli_replay": "rfr_viz.cli.replay",
        "rfr_viz.closed_loop": "rfr_viz.recordings.closed_loop",
        "rfr_viz.contrast": "rfr_viz.panels.contrast",
        "rfr_viz.demo": "rfr_viz.jobs.demo",
        "rfr_viz.encoder_comparison": "rfr_viz.jobs.compare_encoders",
        "rfr_viz.eval_charts": "rfr_viz.charts.evaluation",
        "rfr_viz.evaluation_recording": "rfr_viz.recordings.evaluation",
        "rfr_viz.explain": "rfr_viz.jobs.explain",
        "rfr_viz.live": "rfr_viz.recordings.live rfr_viz.jobs.watch",
        "rfr_viz.live_camera": "rfr_viz.panels.live_camera",
        "rfr_viz.memory_umap": "rfr_viz.panels.umap",
        "rfr_viz.neighbors": "rfr_viz.panels.neighbors",
        "rfr_viz.panel_map": "rfr_viz.panels.map",
        "rfr_viz.panel_report": "rfr_viz.panels.report",
        "rfr_viz.panel_scores": "rfr_viz.panels.scores",
        "rfr_viz.record": "rfr_viz.recordings.replay",
        "rfr_viz.replay": "rfr_viz.jobs.replay",
        "rfr_viz.report_html": "rfr_viz.charts.report_html",
        "rfr_viz.review": "rfr_viz.jobs.review",
        "rfr_viz.share": "rfr_viz.viewer.share",
        "rfr_viz.video_passthrough": "rfr_viz.panels.video_passthrough",
    }
)

install(MOVED)
