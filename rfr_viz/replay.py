"""The `replay` and `compare` jobs: trajectories of a dataset through the detector into `.rrd` files."""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from rfr_viz.memory_umap import MemoryMap, memory_map
from rfr_viz.record import compare_recording, record_replay
from robofailring.data.layouts import detect_layout, load_dataset, load_trajectory
from robofailring.data.model import Trajectory
from robofailring.detector import DEFAULT_K, FailureDetector
from robofailring.encoders import CachedEncoder, encoder_slug, load_encoder
from robofailring.errors import DataError, UnknownTaskError
from robofailring.memory import FailureMemory
from robofailring.pipeline import encoder_spec_for
from robofailring.progress import progress_bar

DEFAULT_OUT: Final[Path] = Path("recordings")
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")


@dataclass(frozen=True)
class ReplayConfig:
    data: Path  # dataset root of any layout, or one episode folder
    memory: Path  # memory directory; its map is cached there (umap.npz)
    out: Path = DEFAULT_OUT  # folder of the .rrd files, one per trajectory
    trajectories: tuple[str, ...] = ()  # `<task>/<episode>` keys or episode names; empty = all
    delta: float | None = None  # default: the memory's calibrated δ, else the paper's 0.92
    k: int = DEFAULT_K  # neighbours retrieved (and logged) per view and frame
    score: str | None = None  # `paper` or `contrast` (default: contrast when the memory has successes)
    gamma: float | None = None  # contrast threshold (default: the memory's calibrated γ, else 0)
    task: str | None = None  # task of an episode folder whose name does not say; on a root, a filter
    leave_one_out: bool = False  # hide each trajectory's own episode from the memory
    encoder: str | None = None  # encoder spec; default: the one that built the memory
    fps: float | None = None  # "time" timeline rate; default: the data's, else 10
    cache_dir: Path | None = None  # embedding cache (default ~/.cache/robofailring)
    device: str | None = None  # torch device for CLIP


@dataclass(frozen=True)
class CompareConfig:
    data: Path  # dataset root of any layout, or one episode folder
    memories: tuple[Path, ...]  # two or more memories, each built with its own encoder
    out: Path = DEFAULT_OUT
    trajectories: tuple[str, ...] = ()
    deltas: tuple[float, ...] = ()  # one δ per memory; default: each memory's calibrated δ
    k: int = DEFAULT_K
    score: str | None = None  # scoring rule of every memory (default: each one's)
    task: str | None = None
    leave_one_out: bool = False
    fps: float | None = None
    cache_dir: Path | None = None
    device: str | None = None


@dataclass
class ReplayResult:
    """Recordings written, and trajectories skipped with the reason (counted and reported)."""

    recordings: list[Path] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)


def recording_name(trajectory: Trajectory, suffix: str = "") -> str:
    """`<task>__<episode>.rrd`, with `/` and other unsafe characters of the episode replaced."""
    episode = _UNSAFE.sub("_", trajectory.episode.replace("/", "_"))
    return f"{_UNSAFE.sub('_', trajectory.task)}__{episode}{suffix}.rrd"


def select_trajectories(data: Path, *, keys: Sequence[str] = (), task: str | None = None) -> list[Trajectory]:
    """The trajectories of a dataset root (optionally by key and task) or of one episode folder."""
    data = Path(data)
    if detect_layout(data) == "episode":
        return [load_trajectory(data, task=task)]
    chosen = load_dataset(data).select(keys=list(keys) or None)
    if task is not None:
        chosen = [trajectory for trajectory in chosen if trajectory.task == task]
        if not chosen:
            raise DataError(f"no trajectory of task {task!r} in {data}")
    return chosen


@dataclass(frozen=True)
class LoadedDetector:
    slug: str
    memory: FailureMemory
    detector: FailureDetector
    map: MemoryMap


def load_detector(
    memory_dir: Path,
    *,
    delta: float | None,
    k: int,
    encoder: str | None,
    cache_dir: Path | None,
    device: str | None,
    score: str | None = None,
    gamma: float | None = None,
) -> LoadedDetector:
    memory = FailureMemory.load(memory_dir)
    spec = encoder or encoder_spec_for(memory)
    cached = CachedEncoder(load_encoder(spec, device=device), cache_dir=cache_dir)
    return LoadedDetector(
        slug=encoder_slug(memory.encoder),
        memory=memory,
        detector=FailureDetector(memory, cached, delta=delta, k=k, rule=score, gamma=gamma),
        map=memory_map(memory, directory=memory_dir),
    )


def replay(config: ReplayConfig) -> ReplayResult:
    """Replay each selected trajectory through the detector into `<out>/<task>__<episode>.rrd`."""
    found = load_detector(
        config.memory,
        delta=config.delta,
        k=config.k,
        score=config.score,
        gamma=config.gamma,
        encoder=config.encoder,
        cache_dir=config.cache_dir,
        device=config.device,
    )
    trajectories = select_trajectories(config.data, keys=config.trajectories, task=config.task)
    result = ReplayResult()
    with progress_bar(total=len(trajectories), desc="replaying", unit="trajectory") as bar:
        for trajectory in trajectories:
            try:
                trace = found.detector.run(trajectory, leave_one_out=config.leave_one_out)
            except (UnknownTaskError, DataError) as error:
                result.skipped.append((trajectory.key, str(error)))
            else:
                out = Path(config.out) / recording_name(trajectory)
                result.recordings.append(
                    record_replay(trajectory, trace, out=out, memory_map=found.map, fps=config.fps)
                )
            bar.update(1)
    return result


def unique_slugs(slugs: Sequence[str]) -> list[str]:
    """Encoder slugs made unique in order (`pixels`, `pixels-2`, …) for entity paths."""
    seen: dict[str, int] = {}
    unique = []
    for slug in slugs:
        seen[slug] = seen.get(slug, 0) + 1
        unique.append(slug if seen[slug] == 1 else f"{slug}-{seen[slug]}")
    return unique


def compare(config: CompareConfig) -> ReplayResult:
    """Replay each trajectory under every memory's encoder into one comparison recording."""
    if len(config.memories) < 2:
        raise ValueError("compare needs at least two memories (--memory A --memory B)")
    if config.deltas and len(config.deltas) != len(config.memories):
        raise ValueError(
            f"{len(config.deltas)} δ values for {len(config.memories)} memories: give one per memory"
        )
    deltas: Sequence[float | None] = config.deltas or [None] * len(config.memories)
    detectors = [
        load_detector(
            memory_dir,
            delta=delta,
            k=config.k,
            score=config.score,
            encoder=None,
            cache_dir=config.cache_dir,
            device=config.device,
        )
        for memory_dir, delta in zip(config.memories, deltas, strict=True)
    ]
    slugs = unique_slugs([found.slug for found in detectors])
    trajectories = select_trajectories(config.data, keys=config.trajectories, task=config.task)
    result = ReplayResult()
    suffix = "__" + "-vs-".join(slugs)
    with progress_bar(total=len(trajectories), desc="comparing", unit="trajectory") as bar:
        for trajectory in trajectories:
            try:
                traces = {
                    slug: found.detector.run(trajectory, leave_one_out=config.leave_one_out)
                    for slug, found in zip(slugs, detectors, strict=True)
                }
            except (UnknownTaskError, DataError) as error:
                result.skipped.append((trajectory.key, str(error)))
            else:
                out = Path(config.out) / recording_name(trajectory, suffix)
                maps = {slug: found.map for slug, found in zip(slugs, detectors, strict=True)}
                result.recordings.append(
                    compare_recording(trajectory, traces, out=out, memory_maps=maps, fps=config.fps)
                )
            bar.update(1)
    return result
