"""The `replay` job, its config and its run: trajectories of a dataset through the detector into `.rrd` files (and
what `compare`, `review` and `watch` share with it: the trajectories selected, a memory's detector with its map,
each recording's name and path)."""

from __future__ import annotations

import hashlib
import logging
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from rfr_viz.jobs.recorded import Recordings
from rfr_viz.panels.map import placer
from rfr_viz.panels.umap import MemoryMap, memory_map
from rfr_viz.recordings.replay import record_replay
from rfr_viz.viewer.rrd import check_recording_file
from robofailring.atomic import check_free, output_lock, remove_file_leftovers
from robofailring.data.grounding import Vocabulary
from robofailring.data.layouts import detect_layout
from robofailring.data.model import Skipped, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_STRIDE, DetectorConfig, check_stride
from robofailring.detection.detector import FailureDetector
from robofailring.detection.loader import detector_from
from robofailring.detection.signal_scores import cameras_alone_note
from robofailring.detection.trace import DetectionTrace, self_match_warning
from robofailring.encoders import EncoderSpec
from robofailring.errors import DataError, SettingError, UnknownTaskError
from robofailring.explain.report import report_for
from robofailring.explain.vlm import VLMAnswer, VLMConfig, ask_vlm
from robofailring.memory.failure import FailureMemory
from robofailring.memory.references import ReferenceCheck
from robofailring.outputs import check_output_folder
from robofailring.progress import progress_bar

_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")

_log = logging.getLogger("robofailring")


@dataclass(frozen=True)
class ReplayConfig:
    # a dataset root of any layout, or one episode folder, how it is read (its task: on a root, a filter;
    # its labels: outcome and symbol shown in the recording)
    data: DataSelection
    detector: DetectorConfig  # the memory (its map is cached there, umap.npz) and how its detector judges
    recordings: Recordings = field(default_factory=Recordings)  # which trajectories, into which folder, how
    stride: int = DEFAULT_STRIDE  # score every stride-th frame; the recording keeps every camera frame
    vlm: VLMConfig | None = None  # ask this VLM about each detection; its answer joins the report


@dataclass
class ReplayResult:
    """Recordings written, trajectories skipped with the reason, and memory images not found."""

    recordings: list[Path] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    skipped_inputs: list[Skipped] = field(default_factory=list)  # folders/files of the data not read
    references: dict[Path, ReferenceCheck] = field(default_factory=dict)  # per memory directory
    vlm_errors: list[tuple[str, str]] = field(default_factory=list)  # (trajectory, why the VLM call failed)
    in_memory: list[str] = field(default_factory=list)  # trajectories that are the memory's own episodes
    verdicts: dict[Path, str] = field(default_factory=dict)  # recording -> what its detector did, one line
    cameras_alone: list[str] = field(default_factory=list)  # trajectories that record no robot signals

    def saw(self, trace: DetectionTrace, trajectory: Trajectory) -> None:
        """Note what a trajectory's trace says beyond its scores, as `detect` says it: a memory holding it,
        no signals of its own (one note for them all), and what it did not score (its blind frames, its
        signals that could not be read), listed with the inputs skipped."""
        key = trajectory.key
        if trace.in_memory and key not in self.in_memory:
            self.in_memory.append(key)
        if trace.cameras_alone and key not in self.cameras_alone:
            self.cameras_alone.append(key)
        listed = set(self.skipped_inputs)
        self.skipped_inputs += [
            s for s in trace.skipped_inputs if s not in trajectory.skipped and s not in listed
        ]

    @property
    def notes(self) -> list[str]:
        """Warnings for stderr: the trajectories that met themselves in the memory (no --leave-one-out),
        and those whose cameras judged alone."""
        notes = [self_match_warning(self.in_memory)] if self.in_memory else []
        return notes + ([cameras_alone_note(self.cameras_alone)] if self.cameras_alone else [])

    def ask(self, vlm: VLMConfig | None, trace: DetectionTrace, trajectory: Trajectory) -> VLMAnswer | None:
        """The VLM's answer about the trace's detection (None: no VLM, or nothing detected); failures are kept."""
        report = report_for(trace, trajectory) if vlm is not None else None
        if vlm is None or report is None:
            return None
        answer = ask_vlm(report, vlm)
        if answer.error is not None:
            self.vlm_errors.append((trajectory.key, answer.error))
        return answer

    @property
    def failure(self) -> DataError | None:
        """Why the replay failed, once its skipped trajectories are listed: no recording was written."""
        if self.recordings:
            return None
        return DataError(f"no recording written ({len(self.skipped)} trajectories skipped)")


def recording_name(trajectory: Trajectory, suffix: str = "") -> str:
    """`<task>__<episode>.rrd`, collision-free: distinct trajectories never share a name.

    Characters outside ``[A-Za-z0-9._+-]`` (and `/`) become `_`; when that changed anything, or the
    task itself could blur the `__` separator, `~` and a digest of the raw task and episode are
    appended (`拾取_方块` and `放置_方块`, or `pick cube` beside `pick_cube`, stay apart).
    """
    task = _UNSAFE.sub("_", trajectory.task)
    episode = _UNSAFE.sub("_", trajectory.episode.replace("/", "_"))
    name = f"{task}__{episode}"
    if (
        task != trajectory.task
        or episode != trajectory.episode
        or "__" in task
        or task.startswith("_")
        or task.endswith("_")
    ):
        raw = f"{trajectory.task}\0{trajectory.episode}".encode()
        name += "~" + hashlib.blake2b(raw, digest_size=6).hexdigest()
    return f"{name}{suffix}.rrd"


def check_speed(speed: float) -> float:
    """A playback speed: finite and ≥ 0, 0 as fast as the detector goes (SettingError otherwise)."""
    if not (math.isfinite(speed) and speed >= 0):
        raise SettingError(f"--speed must be a finite number ≥ 0, got {speed}")
    return speed


def recording_target(out: Path, name: str, written: dict[Path, str], key: str) -> Path:
    """The recording path of one trajectory: never another trajectory's, never over a non-recording."""
    path = Path(out) / name
    if path in written:
        raise DataError(f"trajectories {written[path]} and {key} map to the same recording {path}")
    check_recording_file(path)
    written[path] = key
    return path


def select_trajectories(
    data: DataSelection,
    *,
    keys: Sequence[str] = (),
    skipped: list[Skipped] | None = None,
    vocabulary: Vocabulary | None = None,
) -> list[Trajectory]:
    """The trajectories of a dataset root (optionally by key, and by task: `data.task`) or of one episode
    folder (its labels are not applied).

    What the loader did not read is appended to `skipped`; labels' symbols are checked against
    Table 5 and `vocabulary` (the memory's own symbols).
    """
    if detect_layout(data.root) == "episode":
        trajectory = replace(data, labels=None).load_trajectory()
        if skipped is not None:
            skipped += trajectory.skipped
        return [trajectory]
    dataset = data.load(vocabulary=vocabulary, keys=keys)
    if skipped is not None:
        skipped += dataset.skipped
    chosen = list(dataset.trajectories())
    if data.task is not None:
        chosen = [trajectory for trajectory in chosen if trajectory.task == data.task]
        if not chosen:
            raise DataError(f"no trajectory of task {data.task!r} in {data.root}")
    return chosen


@dataclass(frozen=True)
class LoadedDetector:
    slug: str
    memory: FailureMemory
    detector: FailureDetector
    map: MemoryMap
    references: ReferenceCheck


def load_detector(config: DetectorConfig, data: Path) -> LoadedDetector:
    """The detector of `config` with its memory's cached map and reference check (its notes logged); its
    images are read from under `data` (the data the job reads), its own folder or --data-root only."""
    detector = detector_from(config, trusted=[data])
    for note in detector.uncalibrated:
        _log.warning("warning: %s", note)
    memory = detector.memory
    return LoadedDetector(
        slug=EncoderSpec.slug(memory.encoder),
        memory=memory,
        detector=detector,
        map=memory_map(memory, directory=config.memory_dir),
        references=memory.check_references(read=True),
    )


def replay(config: ReplayConfig) -> ReplayResult:
    """Replay each selected trajectory through the detector into `<out>/<task>__<episode>.rrd`."""
    check_stride(config.stride)
    out = config.recordings.out
    check_output_folder(out, inputs=[config.data.root, config.detector.memory])
    with output_lock(out):
        remove_file_leftovers(out)
        return _replay(config)


def _replay(config: ReplayConfig) -> ReplayResult:
    found, recordings = load_detector(config.detector, config.data.root), config.recordings
    result = ReplayResult(references={config.detector.memory_dir: found.references})
    trajectories = select_trajectories(
        config.data,
        keys=recordings.trajectories,
        skipped=result.skipped_inputs,
        vocabulary=found.detector.memory.vocabulary,
    )
    check_free(recordings.out / recording_name(trajectory) for trajectory in trajectories)
    written: dict[Path, str] = {}
    with progress_bar(total=len(trajectories), desc="replaying", unit="trajectory") as bar:
        for trajectory in trajectories:
            try:
                trace = found.detector.run(
                    trajectory,
                    leave_one_out=recordings.leave_one_out,
                    stride=config.stride,
                    keep_queries=False,
                    place=placer(found.map, trajectory.task),
                )
            except (UnknownTaskError, DataError) as error:
                result.skipped.append((trajectory.key, str(error)))
            else:
                result.saw(trace, trajectory)
                result.skipped_inputs += trace.short_views
                out = recording_target(recordings.out, recording_name(trajectory), written, trajectory.key)
                answer = result.ask(config.vlm, trace, trajectory)
                result.recordings.append(
                    record_replay(
                        trajectory,
                        trace,
                        out=out,
                        memory_map=found.map,
                        fps=recordings.fps,
                        camera_codec=recordings.camera_codec,
                        vlm_answer=answer,
                    )
                )
                result.verdicts[result.recordings[-1]] = trace.verdict()
            bar.update(1)
    return result
