"""The generate job: its config (`GenerateConfig`) and its run (`simulate`, `generate_dataset` with a progress
bar): episodes in a process pool, written atomically in the project's layout."""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import zlib
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.atomic import atomic_directory
from robofailring.data.images import write_png
from robofailring.data.layouts import PROJECT_FORMAT, PROJECT_MANIFEST, read_project_manifest
from robofailring.data.layouts.project import SIGNALS_FILE
from robofailring.errors import DataError, SettingError
from robofailring.jsontext import parse_json
from robofailring.outputs import check_folder
from robofailring.progress import progress_bar
from robofailring.sim.appearance import look_mode
from robofailring.sim.cameras import VIEWS
from robofailring.sim.episode import DURATION_S, EpisodeResult, episode_fps, run_episode
from robofailring.sim.perturb import FAILURE_MODES, KINDS, SUCCESS
from robofailring.sim.scene import PHYSICS_HZ
from robofailring.sim.signals import SIGNALS
from robofailring.sim.tasks import TASKS

FORMAT_VERSION: Final[int] = 1
GENERATOR: Final[str] = "robofailring.sim"
#: Bumped whenever the simulator's output changes for the same config (invalidates caches). 2: the arm drawn
#: with low-poly meshes (robot.LOW_POLY_LINKS); 3: onset_frame; 4: signals.
SIM_VERSION: Final[int] = 4
_SUCCESS_RETRIES: Final[int] = 3
#: The largest image side generated: pybullet's CPU renderer takes ~3 s a frame of three views at
#: 1024 px (two minutes an episode of 40 frames), and a side far beyond ends the worker with bad_alloc.
MAX_IMAGE_SIZE: Final[int] = 1024


@dataclass(frozen=True)
class GenerateConfig:
    """What to generate: `episodes` per kind per task; a kind is a failure family, a concrete
    mode (``rotation_x``) or ``success``; axial families draw their axis per episode. `look` is
    ``in``, ``ood`` (every episode in the ``ood`` split) or ``random`` (`robofailring.sim.appearance`);
    ``ood=True`` is ``look="ood"`` and, after construction, `ood` says whether the look is ``ood``."""

    out: Path
    tasks: tuple[str, ...] = TASKS
    episodes: int = 2
    modes: tuple[str, ...] = KINDS
    success_episodes: int | None = None  # success episodes per task (default: `episodes`)
    seed: int = 0
    ood: bool = False
    image_size: int = 128
    frames: int = 40
    workers: int = 2
    look: str = "in"

    def __post_init__(self) -> None:
        object.__setattr__(self, "out", Path(self.out))
        object.__setattr__(self, "look", look_mode(self.look, ood=self.ood))
        object.__setattr__(self, "ood", self.look == "ood")
        object.__setattr__(self, "tasks", tuple(self.tasks))
        object.__setattr__(self, "modes", tuple(self.modes))
        unknown = [t for t in self.tasks if t not in TASKS]
        if unknown or not self.tasks:
            raise SettingError(f"unknown task(s) {unknown}; expected some of {list(TASKS)}")
        allowed = (*KINDS, *FAILURE_MODES)
        bad = [m for m in self.modes if m not in allowed]
        if bad or not self.modes:
            raise SettingError(f"unknown mode(s) {bad}; expected some of {list(allowed)}")
        if len(set(self.modes)) != len(self.modes) or len(set(self.tasks)) != len(self.tasks):
            raise SettingError(
                f"tasks and modes must not repeat, got tasks {list(self.tasks)} and modes {list(self.modes)}"
            )
        if self.success_episodes is not None and self.success_episodes < 0:
            raise SettingError(f"--success-episodes must be at least 0, got {self.success_episodes}")
        for flag, value, least in (
            ("--episodes", self.episodes, 1),
            ("--frames", self.frames, 2),
            ("--image-size", self.image_size, 16),
            ("--workers", self.workers, 1),
        ):
            if value < least:
                raise SettingError(f"{flag} must be at least {least}, got {value}")
        if self.image_size > MAX_IMAGE_SIZE:
            raise SettingError(
                f"--image-size must be at most {MAX_IMAGE_SIZE} px (the simulator renders on the CPU), "
                f"got {self.image_size}"
            )

    def episodes_of(self, kind: str) -> int:
        """How many episodes of one kind are run per task."""
        if kind == SUCCESS and self.success_episodes is not None:
            return self.success_episodes
        return self.episodes

    @property
    def total_episodes(self) -> int:
        return len(self.tasks) * sum(self.episodes_of(kind) for kind in self.modes)

    def content(self) -> dict[str, Any]:
        """Every parameter that decides the dataset's content (not where it goes, nor how fast)."""
        content: dict[str, Any] = {
            "tasks": list(self.tasks),
            "episodes": self.episodes,
            "modes": list(self.modes),
            "seed": self.seed,
            "ood": self.ood,
            "image_size": self.image_size,
            "frames": self.frames,
            "duration_s": DURATION_S,
            "physics_hz": PHYSICS_HZ,
            "sim_version": SIM_VERSION,
        }
        if self.success_episodes is not None:
            content["success_episodes"] = self.success_episodes
        if self.look == "random":  # absent for `in` and `ood`: their sets cached before `look` still hold
            content["look"] = self.look
        return content


@dataclass(frozen=True)
class _Job:
    task: str
    kind: str
    repeat: int
    episode: int
    seed: int
    look: str
    image_size: int
    frames: int
    root: str = field(default="")


def episode_seed(seed: int, task: str, kind: str, repeat: int) -> int:
    """A stable per-episode seed (the same in every process and Python version)."""
    return (seed * 1_000_003 + zlib.crc32(f"{task}/{kind}/{repeat}".encode())) % 2**31


def _jobs(config: GenerateConfig, root: Path) -> list[_Job]:
    jobs = []
    for task in config.tasks:
        first = 0
        for kind in config.modes:
            count = config.episodes_of(kind)
            for repeat in range(count):
                jobs.append(
                    _Job(
                        task=task,
                        kind=kind,
                        repeat=repeat,
                        episode=first + repeat,
                        seed=episode_seed(config.seed, task, kind, repeat),
                        look=config.look,
                        image_size=config.image_size,
                        frames=config.frames,
                        root=str(root),
                    )
                )
            first += count
    return jobs


def episode_dir_name(task: str, label: str | None, episode: int) -> str:
    """The AHA-style folder name: ``<task>_<label>_episode<e>`` or ``<task>_success_episode<e>``."""
    return f"{task}_{label or SUCCESS}_episode{episode}"


def _simulate(job: _Job, seed: int, staging: Path) -> EpisodeResult:
    """Run one episode, streaming its frames to PNG files in `staging`, then its signals to `signals.npz`."""
    if staging.exists():
        shutil.rmtree(staging)
    staging.mkdir()
    with run_episode(
        job.task, job.kind, seed, look=job.look, image_size=job.image_size, frames=job.frames
    ) as run:
        for index, images in enumerate(run):
            for view in VIEWS:
                write_png(staging / f"{view}_{index}.png", images[view])
        result = run.run_to_end()
        np.savez(staging / SIGNALS_FILE, **run.signals())  # type: ignore[arg-type]  # numpy's stub types **kwds as allow_pickle
        return result


def _run_job(job: _Job) -> dict[str, Any]:
    """Simulate one episode and return its manifest record.

    An unperturbed run that misses its goal has no failure symbol to carry; it is run again
    from a derived seed (it never happened in testing; the record counts the retries).
    """
    root = Path(job.root)
    staging = root / f".staging-{job.task}-{job.episode}"
    seed, retries = job.seed, 0
    result = _simulate(job, seed, staging)
    while result.perturbation is None and not result.goal.passed and retries < _SUCCESS_RETRIES:
        retries += 1
        seed = episode_seed(job.seed, job.task, job.kind, 1000 + retries)
        result = _simulate(job, seed, staging)
    if result.perturbation is None and not result.goal.passed:
        raise RuntimeError(f"{job.task}: an unperturbed episode missed its goal {_SUCCESS_RETRIES + 1} times")
    name = episode_dir_name(job.task, result.label, job.episode)
    os.replace(staging, root / name)
    perturbation = result.perturbation
    return {
        "dir": name,
        "episode": name,
        "task": job.task,
        "label": result.label,
        "outcome": result.outcome,
        "views": list(VIEWS),
        "frames": result.frames,
        "onset_frame": result.onset_frame,  # the frame the failure's perturbation starts at (null: success)
        "fps": episode_fps(job.frames),
        "seed": seed,
        "retries": retries,
        "split": "ood" if job.look == "ood" else ("train" if job.episode % 2 == 0 else "test"),
        "kind": job.kind,
        "perturbation": None if perturbation is None else perturbation.mode,
        "perturbed_waypoint": None if perturbation is None else perturbation.waypoint,
        "attempted_label": None if perturbation is None else perturbation.symbol,
        "goal_check": result.goal.to_json(),
        "signals": _signal_records(root / name / SIGNALS_FILE),
    }


def _signal_records(path: Path) -> dict[str, Any]:
    """The manifest's description of an episode's signals file: each signal's kind and dimension names."""
    with np.load(path, allow_pickle=False) as stored:
        names = list(stored.files)
    return {
        "file": SIGNALS_FILE,
        "signals": {name: {"kind": SIGNALS[name][0], "names": list(SIGNALS[name][1])} for name in names},
    }


def _execute(jobs: list[_Job], workers: int) -> Iterator[dict[str, Any]]:
    if workers == 1 or len(jobs) == 1:
        yield from map(_run_job, jobs)
        return
    # Each worker process opens its own pybullet DIRECT client; spawn keeps them independent of
    # whatever the parent has loaded (torch, a GUI client, ...). An executor, not a Pool: a worker
    # that dies while starting (a script without a `__main__` guard re-runs itself in each one)
    # breaks it with an error here, where a Pool would start new workers forever.
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=context) as pool:
        pending: list[Any] = []
        try:  # a worker that dies at once breaks the pool while jobs are still being submitted
            for job in jobs:
                pending.append(pool.submit(_run_job, job))
            for done in as_completed(pending):
                yield done.result()
        except BrokenProcessPool as error:
            for future in pending:
                future.cancel()
            raise SettingError(
                f"a simulation worker process stopped before finishing its episode ({error}): it crashed "
                "or ran out of memory, or, when generate_dataset is called from a script without "
                '`if __name__ == "__main__":` around the call, it re-ran the script (pass workers=1 to '
                "see the error in this process)"
            ) from error


def _cached(config: GenerateConfig) -> bool:
    path = config.out / PROJECT_MANIFEST
    try:
        manifest = parse_json(path.read_bytes(), source=str(path))
    except (OSError, DataError):
        return False
    if (
        not isinstance(manifest, dict)
        or manifest.get("generator") != GENERATOR
        or manifest.get("config") != config.content()
    ):
        return False
    return all((config.out / record["dir"]).is_dir() for record in manifest.get("episodes", []))


def _check_replaceable(out: Path) -> None:
    """Refuse to replace a non-empty folder that is not a dataset this generator wrote (or a file)."""
    check_folder(out, holds="a generated dataset")
    if not out.exists():
        return
    try:
        manifest = parse_json((out / PROJECT_MANIFEST).read_bytes(), source=str(out / PROJECT_MANIFEST))
        ours = manifest.get("generator") == GENERATOR
    except (OSError, DataError, AttributeError):
        ours = False
    if not ours and any(out.iterdir()):
        raise DataError(
            f"{out} exists and is not a dataset written by {GENERATOR}; refusing to replace it "
            "(choose another output folder or remove it)"
        )


def manifest_for(config: GenerateConfig, records: list[dict[str, Any]]) -> dict[str, Any]:
    order = {(t, m): i for i, (t, m) in enumerate((t, m) for t in config.tasks for m in config.modes)}
    records = sorted(records, key=lambda r: (order[(r["task"], r["kind"])], r["dir"]))
    failures = [r for r in records if r["perturbation"] is not None]
    return {
        "format": PROJECT_FORMAT,
        "format_version": FORMAT_VERSION,
        "generator": GENERATOR,
        "seed": config.seed,
        "fps": episode_fps(config.frames),
        "image_size": config.image_size,
        "ood": config.ood,
        "look": config.look,
        "views": list(VIEWS),
        "tasks": list(config.tasks),
        "config": config.content(),
        "summary": {
            "episodes": len(records),
            "attempted_failures": len(failures),
            "failed": sum(r["outcome"] == "failure" for r in failures),
        },
        "episodes": records,
    }


def describe_dataset(root: Path) -> str:
    """One line about a generated dataset: its episodes, how many are failures, its frame rate."""
    manifest = read_project_manifest(root)
    failures = sum(e["outcome"] == "failure" for e in manifest["episodes"])
    return (
        f"dataset {root}: {len(manifest['episodes'])} episodes ({failures} failures), {manifest['fps']} fps"
    )


def generate_dataset(config: GenerateConfig, *, progress: Callable[[int], None] | None = None) -> Path:
    """Generate the dataset described by `config` at `config.out` and return that path.

    An output folder already holding a dataset of the identical config is returned as it is.
    Otherwise everything is written into a temporary folder beside it and swapped in at the end,
    so nothing half-written ever carries the final name.
    """
    out = config.out
    if _cached(config):
        return out
    _check_replaceable(out)
    with atomic_directory(out) as root:
        records = []
        for record in _execute(_jobs(config, root), config.workers):
            records.append(record)
            if progress is not None:
                progress(1)
        manifest = manifest_for(config, records)
        (root / PROJECT_MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n", encoding="utf-8")
    return out


def simulate(config: GenerateConfig, *, label: str = "") -> Path:
    """`generate_dataset` with a progress bar (a folder already holding the same set is returned as is)."""
    with progress_bar(total=config.total_episodes, desc=f"simulating {label}".strip(), unit="episode") as bar:
        return generate_dataset(config, progress=bar.update)
