"""The triage job: rank every episode of a dataset, then write `triage.csv` (a labels file to fill),
`triage.rrd` (every episode at once), `triage.html` and a replay of the first episodes, each opening
at its peak (`robofailring open`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from rfr_viz.charts.triage_html import TRIAGE_HTML, write_triage_page
from rfr_viz.codecs import CameraCodec
from rfr_viz.jobs.replay import recording_name
from rfr_viz.panels.images import thumbnail_jpeg
from rfr_viz.panels.map import placer
from rfr_viz.panels.umap import memory_map
from rfr_viz.recordings.replay import record_replay
from rfr_viz.recordings.triage import record_triage
from rfr_viz.viewer.control import open_at_command, open_command
from rfr_viz.viewer.rrd import check_recording_file
from robofailring.atomic import output_lock, remove_file_leftovers
from robofailring.errors import SettingError
from robofailring.outputs import check_output_folder, check_own_files
from robofailring.progress import progress_bar
from robofailring.triage import TriageConfig, TriageResult, run_triage
from robofailring.triage.table import TRIAGE_NAME, check_table, table_rows, write_table

TRIAGE_RECORDING: Final[str] = "triage.rrd"
REPLAYS: Final[str] = "replays"  # the folder of the per-episode replays, beside triage.rrd
DEFAULT_REPLAYS: Final[int] = 20


@dataclass(frozen=True)
class TriageOutcome:
    """The ranking and the files it was written to."""

    result: TriageResult
    table: Path  # triage.csv
    recording: Path  # triage.rrd
    page: Path  # triage.html
    replays: dict[str, Path] = field(default_factory=dict)  # by episode key: its replay, opening at its peak

    def summary(self, data: Path, *, shown: int = 10) -> str:
        """What the command prints: the top of the ranking, the files written and the next step."""
        ranked = self.result.ranked
        lines = [f"{len(ranked)} episode(s) ranked, least normal first:"]
        for score in ranked[:shown]:
            what = (
                f"score {score.rank_score:.3f} at frame {score.frame} ({score.view})"
                if score.scored
                else "not scored"
            )
            lines.append(f"  #{score.rank} {score.key}: {what}")
        lines.append(
            f"\nwrote {self.table} (fill outcome, symbol, description), {self.recording} "
            f"(open with: {open_command(self.recording)}) and {self.page}"
        )
        if self.replays:
            first = next(iter(self.replays.values()))
            lines.append(f"{len(self.replays)} replay(s) in {first.parent}; each opens at its peak, e.g.:")
            lines.append(f"  {open_at_command(first)}")
        lines.append(
            f"then: robofailring build-memory {data} --labels {self.table} --out MEMORY (or --add-to MEMORY), "
            "and triage again with --memory MEMORY"
        )
        return "\n".join(lines)


def triage(
    config: TriageConfig, *, replays: int = DEFAULT_REPLAYS, camera_codec: CameraCodec = CameraCodec.AUTO
) -> TriageOutcome:
    """Rank every episode of `config.data` and write the outputs into `config.out`, holding its lock.

    `replays`: how many episodes, from the top of the ranking, get a replay (-1: every one). A
    `triage.csv` already there is merged into (what a person filled in is kept); a file there that is
    not a labels CSV, or not a recording where one goes, is refused before any work.
    """
    if replays < -1:
        raise SettingError(f"--replays must be a number of episodes, or -1 for all of them, got {replays}")
    out = Path(config.out)
    check_output_folder(out, inputs=[config.data.root, config.memory, config.known_good])
    with output_lock(out):
        remove_file_leftovers(out)
        remove_file_leftovers(out / REPLAYS)
        check_table(out / TRIAGE_NAME)
        check_recording_file(out / TRIAGE_RECORDING)
        check_own_files([out / TRIAGE_HTML])
        result = run_triage(config)
        recorded = _replays(config, result, replays if replays >= 0 else len(result.ranked), camera_codec)
        commands = {key: open_at_command(path) for key, path in recorded.items()}
        with progress_bar(total=len(result.ranked), desc="thumbnails", unit="episode") as bar:
            thumbnails = {}
            for score in result.ranked:
                if score.thumbnail is not None:
                    thumbnails[score.key] = thumbnail_jpeg(score.thumbnail)
                bar.update(1)
        labelled = {key: t for key, t in result.trajectories.items() if t.outcome is not None}
        table = write_table(
            out / TRIAGE_NAME, table_rows(result.ranked, labelled=labelled, open_commands=commands)
        )
        recording = record_triage(
            result.ranked,
            out=out / TRIAGE_RECORDING,
            thumbnails=thumbnails,
            open_commands=commands,
            notes=result.notes,
        )
        page = write_triage_page(
            result.ranked,
            out / TRIAGE_HTML,
            thumbnails=thumbnails,
            open_commands=commands,
            notes=result.notes,
            files={"triage.rrd (every episode at once)": recording, "triage.csv (to fill)": table},
        )
    return TriageOutcome(result=result, table=table, recording=recording, page=page, replays=recorded)


def _replays(
    config: TriageConfig, result: TriageResult, count: int, camera_codec: CameraCodec
) -> dict[str, Path]:
    """A replay of each of the first `count` scored episodes, opening at its peak (its own episode left out)."""
    chosen = [score for score in result.ranked if score.scored][:count]
    if not chosen:
        return {}
    detector = result.detector
    mapped = memory_map(detector.memory, directory=config.memory)
    folder = Path(config.out) / REPLAYS
    written: dict[str, Path] = {}
    with progress_bar(total=len(chosen), desc="replays", unit="episode") as bar:
        for score in chosen:
            trajectory = result.trajectories[score.key]
            path = folder / recording_name(trajectory)
            check_recording_file(path)
            trace = detector.run(
                trajectory, leave_one_out=True, keep_queries=False, place=placer(mapped, trajectory.task)
            )
            written[score.key] = record_replay(
                trajectory,
                trace,
                out=path,
                memory_map=mapped,
                focus_frame=score.frame,
                camera_codec=camera_codec,
            )
            bar.update(1)
    return written
