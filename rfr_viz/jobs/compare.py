"""The `compare` job, its config and its run: each trajectory under two or more memories' detectors into one
comparison recording."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from rfr_viz.jobs.recorded import Recordings
from rfr_viz.jobs.replay import (
    ReplayResult,
    load_detector,
    recording_name,
    recording_target,
    select_trajectories,
)
from rfr_viz.panels.map import placer
from rfr_viz.recordings.replay import compare_recording
from robofailring.atomic import check_free, output_lock, remove_file_leftovers
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.errors import DataError, SettingError, UnknownTaskError
from robofailring.outputs import check_output_folder, unique_names
from robofailring.progress import progress_bar


@dataclass(frozen=True)
class CompareConfig:
    data: (
        DataSelection  # a dataset root of any layout, or one episode folder, how it is read (not its labels)
    )
    detectors: tuple[DetectorConfig, ...]  # two or more memories, each built with its own encoder
    recordings: Recordings = field(default_factory=Recordings)  # which trajectories, into which folder, how


def compare(config: CompareConfig) -> ReplayResult:
    """Replay each trajectory under every memory's encoder into one comparison recording."""
    out = config.recordings.out
    check_output_folder(out, inputs=[config.data.root, *(each.memory for each in config.detectors)])
    with output_lock(out):
        remove_file_leftovers(out)
        return _compare(config)


def _compare(config: CompareConfig) -> ReplayResult:
    if len(config.detectors) < 2:
        raise SettingError(
            f"compare needs at least two memories (--memory A --memory B), got {len(config.detectors)}"
        )
    detectors, recordings = (
        [load_detector(each, config.data.root) for each in config.detectors],
        config.recordings,
    )
    slugs = unique_names([found.slug for found in detectors])
    result = ReplayResult(
        references={
            each.memory_dir: found.references for each, found in zip(config.detectors, detectors, strict=True)
        }
    )
    trajectories = select_trajectories(
        replace(config.data, labels=None), keys=recordings.trajectories, skipped=result.skipped_inputs
    )
    suffix = "__" + "-vs-".join(slugs)
    check_free(recordings.out / recording_name(trajectory, suffix) for trajectory in trajectories)
    written: dict[Path, str] = {}
    with progress_bar(total=len(trajectories), desc="comparing", unit="trajectory") as bar:
        for trajectory in trajectories:
            try:
                traces = {
                    slug: found.detector.run(
                        trajectory,
                        leave_one_out=recordings.leave_one_out,
                        keep_queries=False,
                        place=placer(found.map, trajectory.task),
                    )
                    for slug, found in zip(slugs, detectors, strict=True)
                }
            except (UnknownTaskError, DataError) as error:
                result.skipped.append((trajectory.key, str(error)))
            else:
                for trace in traces.values():
                    result.saw(trace, trajectory)
                result.skipped_inputs += next(iter(traces.values())).short_views  # the same in every memory
                out = recording_target(
                    recordings.out, recording_name(trajectory, suffix), written, trajectory.key
                )
                maps = {slug: found.map for slug, found in zip(slugs, detectors, strict=True)}
                result.recordings.append(
                    compare_recording(
                        trajectory,
                        traces,
                        out=out,
                        memory_maps=maps,
                        fps=recordings.fps,
                        camera_codec=recordings.camera_codec,
                    )
                )
            bar.update(1)
    return result
