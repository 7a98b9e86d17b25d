"""The success memory: what normal runs looked like, frame by frame, for success contrast.

Per success trajectory, view and frame t it holds ``u = norm([norm f(I_0) ‖ norm f(I_t)])`` (the
same pairing as the failure memory's eq. 2–4, with the current frame in place of the end frame),
searched within the task. The first frame of every *failure* trajectory is a normal state too (the
failure has not happened yet), so each failure view adds its ``(I_0 ‖ I_0)`` as a one-frame run:
without it, frame 0 of a new run matches a "nothing happened" failure better than any success. It lives beside the failure memory in the same folder: `success.faiss`
(all vectors) and `success_runs.jsonl` (one line per run and view: task, episode, view and the
references of its frames, in row order).
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.model import Frame, Outcome, Skipped, Trajectory
from robofailring.encoders.base import BLANK_REASON, frame_ranges, unusable
from robofailring.encoders.cache import CachedEncoder
from robofailring.errors import MemoryFormatError
from robofailring.memory.format import read_jsonl
from robofailring.memory.index import TaskIndexSet
from robofailring.memory.index_file import read_index_file
from robofailring.memory.pairs import check_pairing, pair_vectors
from robofailring.memory.references import absolute_reference, to_stored
from robofailring.memory.thinning import check_step, thin_run

INDEX: Final[str] = "success.faiss"  # memories written before per-task index files
INDEX_STEM: Final[str] = "success"  # success.<n>.faiss, one per task (robofailring.memory.index)
RUNS: Final[str] = "success_runs.jsonl"
MANIFEST_KEY: Final[str] = "successes"  # the failure memory manifest's section on the success memory


def _run_fields(fields: Any) -> dict[str, Any]:
    """A success_runs.jsonl row's fields, each of the type `SuccessRun` holds (TypeError otherwise)."""
    if not isinstance(fields, dict):
        raise TypeError(f"a run is a JSON object, not {fields!r}")
    wrong = [k for k in ("task", "episode", "view", "kind") if k in fields and not isinstance(fields[k], str)]
    if wrong:
        raise TypeError(f"{wrong[0]!r} must be a string, not {fields[wrong[0]]!r}")
    frames, numbers = fields.get("frames"), fields.get("frame_numbers", [])
    if not isinstance(frames, list) or not all(isinstance(f, str) for f in frames):
        raise TypeError(f"'frames' must be a list of image references, not {frames!r}")
    if not isinstance(numbers, list) or not all(type(n) is int for n in numbers):
        raise TypeError(f"'frame_numbers' must be a list of whole numbers, not {numbers!r}")
    return fields


def run_frames(trajectory: Trajectory) -> Iterator[tuple[str, list[Frame]]]:
    """The frames `SuccessMemory.build` encodes of a labelled trajectory, per view of ≥ 2 frames: all of a
    success run's, the first of a failure run's (its start, before anything went wrong); none of an
    unlabelled one's."""
    if trajectory.outcome is None:
        return
    for view, frames in trajectory.views.items():
        if len(frames) >= 2:
            yield view, list(frames) if trajectory.outcome is Outcome.SUCCESS else [frames[0]]


@dataclass(frozen=True)
class SuccessRun:
    """One view of one success trajectory: its rows in the success memory are its frames, in order."""

    task: str
    episode: str
    view: str
    frames: tuple[str, ...]  # references (paths) of the frames kept in the memory, in time order
    kind: str = "success"  # or "failure-start": the first frame of a failure run
    frame_numbers: tuple[int, ...] = ()  # each kept frame's number in the run (empty: 0, 1, 2, …)

    def frame_number(self, row: int) -> int:
        """The run's frame number of its `row`-th kept frame (thinning keeps only some)."""
        return self.frame_numbers[row] if self.frame_numbers else row


@dataclass(frozen=True)
class SuccessMatch:
    """The nearest success frame to a query: run, frame index and cosine similarity S⁺."""

    index: int
    similarity: float
    run: SuccessRun
    row: int  # which of the run's kept frames

    @property
    def frame(self) -> int:
        """The frame number in the success run."""
        return self.run.frame_number(self.row)

    @property
    def image(self) -> str:
        return self.run.frames[self.row]


class SuccessMemory:
    """Success-run vectors searchable top-1 within one task (Faiss inner product per task)."""

    def __init__(
        self,
        vectors: np.ndarray | None,
        runs: Sequence[SuccessRun],
        *,
        dim: int,
        index: TaskIndexSet | None = None,
        offered: int | None = None,
        thinning: Mapping[str, Any] | None = None,
    ) -> None:
        """`vectors` (rows in run order) build a per-task index (`task_index`: exact, or approximate
        for large tasks); a saved memory passes its `index` instead and no vectors."""
        runs = list(runs)
        sizes = np.asarray([len(run.frames) for run in runs], dtype=np.int64)
        count = int(sizes.sum())
        if vectors is not None:
            vectors = np.ascontiguousarray(vectors, dtype=np.float32).reshape(-1, dim)
            if count != len(vectors):
                raise MemoryFormatError(
                    f"{len(runs)} success runs hold {count} frames but {len(vectors)} vectors"
                )
        self.vectors = vectors  # None for a loaded memory: its index holds them (quantised when large)
        self.runs = runs
        self.dim = dim
        self.row_run = np.repeat(np.arange(len(runs), dtype=np.int64), sizes)
        self.row_frame = np.arange(count, dtype=np.int64) - np.repeat(np.cumsum(sizes) - sizes, sizes)
        self.offered = count if offered is None else offered
        self.thinning = dict(thinning or {})
        if index is None:
            assert vectors is not None
            tasks = np.asarray([run.task for run in runs], dtype=object)[self.row_run]
            episodes = np.asarray([run.episode for run in runs], dtype=object)[self.row_run]
            index = TaskIndexSet.build(vectors, tasks.tolist(), episodes.tolist())
        if len(index) != count:
            raise MemoryFormatError(f"the success index holds {len(index)} frames, its runs {count}")
        self.index = index

    # ---------------------------------------------------------------- building
    @classmethod
    def build(
        cls,
        trajectories: Iterable[Trajectory],
        encoder: CachedEncoder,
        *,
        step: float,
        pairing: str,
        progress: Callable[[int], None] | None = None,
        cap: int | None = None,
        skipped: list[Skipped] | None = None,
    ) -> SuccessMemory:
        """The frames of every view (≥ 2 frames) of the success trajectories that add something
        (`thinning.thin_run`: cosine `step`, at most `cap` per run; step 0 keeps every frame), and
        the first frame of every failure view; unlabelled trajectories are ignored. `pairing`: the
        failure memory's (`robofailring.memory.pairs`). A frame blank to the encoder is never kept (a
        view whose first frame is: none of it), and is listed in `skipped`."""
        check_step(step)
        check_pairing(pairing)
        trajectories = list(trajectories)
        encoder.prefetch(frame for t in trajectories for _, frames in run_frames(t) for frame in frames)
        runs: list[SuccessRun] = []
        vectors: list[np.ndarray] = []
        offered = 0
        for trajectory in trajectories:
            if trajectory.outcome is None:
                continue
            success = trajectory.outcome is Outcome.SUCCESS
            for view, frames in run_frames(trajectory):
                embeddings = encoder.encode_frames(frames)
                blank = unusable(embeddings)
                offered += len(frames)
                if blank.any() and skipped is not None:
                    skipped.append(_blank_frames(trajectory, view, frames, blank))
                if blank[0]:
                    continue
                paired = pair_vectors(
                    np.repeat(embeddings[:1], len(frames), axis=0), embeddings, pairing=pairing
                )
                usable = np.flatnonzero(~blank)
                kept = (
                    usable[thin_run(paired[usable], step=step, cap=cap).kept]
                    if success
                    else np.zeros(1, np.int64)
                )
                vectors.append(paired[kept])
                runs.append(
                    SuccessRun(
                        trajectory.task,
                        trajectory.episode,
                        view,
                        tuple(absolute_reference(frames[int(t)].reference) for t in kept),
                        kind="success" if success else "failure-start",
                        frame_numbers=tuple(int(t) for t in kept) if len(kept) < len(frames) else (),
                    )
                )
            if progress is not None:
                progress(1)
        dim = encoder.dim * 2
        stacked = np.concatenate(vectors) if vectors else np.zeros((0, dim), dtype=np.float32)
        return cls(stacked, runs, dim=dim, offered=offered, thinning={"step": step, "cap": cap})

    def extended(self, other: SuccessMemory) -> SuccessMemory:
        """This memory with another one's runs added (e.g. success runs seen in deployment)."""
        if other.dim != self.dim:
            raise MemoryFormatError(
                f"success memories of dimension {self.dim} and {other.dim} cannot be joined"
            )
        if self.vectors is None or other.vectors is None:
            raise MemoryFormatError(
                "a success memory read from disk cannot be extended: rebuild it with the new runs"
            )
        return SuccessMemory(
            np.concatenate([self.vectors, other.vectors]),
            [*self.runs, *other.runs],
            dim=self.dim,
            offered=self.offered + other.offered,
            thinning=self.thinning,
        )

    # ---------------------------------------------------------------- queries
    def __len__(self) -> int:
        return len(self.row_run)

    @property
    def success_runs(self) -> int:
        """Runs (views) of success trajectories, not counting failure starts."""
        return sum(run.kind == "success" for run in self.runs)

    @property
    def tasks(self) -> list[str]:
        return self.index.tasks

    def has_task(self, task: str) -> bool:
        return task in self.index.by_task

    def search(
        self, queries: np.ndarray, task: str, *, exclude_episode: str | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """S⁺ per query row: (max cosine to the task's success frames, its row id); NaN and -1 when none."""
        queries = np.ascontiguousarray(np.atleast_2d(queries), dtype=np.float32)
        if queries.shape[1] != self.dim:
            raise MemoryFormatError(
                f"query dimension {queries.shape[1]} != success memory dimension {self.dim}"
            )
        if not self.has_task(task):
            return np.full(len(queries), np.nan, np.float32), np.full(len(queries), -1, np.int64)
        similarities, ids = self.index.search(queries, task, 1, exclude_episode=exclude_episode)
        return similarities[:, 0], ids[:, 0]

    def match(self, similarity: float, index: int) -> SuccessMatch | None:
        """The match object of one search result row, or None for -1."""
        if index < 0:
            return None
        return SuccessMatch(
            index=int(index),
            similarity=float(similarity),
            run=self.runs[int(self.row_run[index])],
            row=int(self.row_frame[index]),
        )

    # ---------------------------------------------------------------- storage
    def manifest(self) -> dict[str, Any]:
        """The failure memory manifest's `successes` section: counts by task."""
        return {
            "count": len(self),
            "offered": self.offered,
            "thinning": self.thinning,
            "index": self.index.manifest(INDEX_STEM),
            "runs": len(self.runs),
            "success_runs": self.success_runs,
            "failure_starts": len(self.runs) - self.success_runs,
            "episodes": len({(run.task, run.episode) for run in self.runs if run.kind == "success"}),
            "tasks": dict(sorted(Counter(run.task for run in self.runs if run.kind == "success").items())),
            "views": sorted({run.view for run in self.runs}),
        }

    def write(self, directory: Path, *, root: Path | None = None) -> None:
        """Write the index and runs into `directory` (the failure memory's temporary folder).

        Frame references under `root` (the memory's data root) are stored relative to it."""
        self.index.write(directory, INDEX_STEM)
        with (directory / RUNS).open("w", encoding="utf-8") as handle:
            for run in self.runs:
                frames = [to_stored(frame, root) for frame in run.frames]
                handle.write(json.dumps(asdict(run) | {"frames": frames}) + "\n")

    @classmethod
    def read(
        cls,
        directory: Path,
        section: dict[str, Any],
        dim: int,
        *,
        resolve: Callable[[str], str] | None = None,
    ) -> SuccessMemory:
        """Read what `write` wrote and check it against the manifest's `successes` section (vectors of `dim`).

        `resolve` turns stored frame references into absolute ones (see `references.stored_resolver`)."""

        def parse(record: Any) -> SuccessRun:
            fields = _run_fields(record)
            stored = tuple(resolve(f) if resolve else f for f in fields["frames"])
            numbers = tuple(int(n) for n in fields.get("frame_numbers", ()))
            return SuccessRun(**{**fields, "frames": stored, "frame_numbers": numbers})

        runs = read_jsonl(directory / RUNS, parse, what="success run")
        frames = sum(len(run.frames) for run in runs)
        if frames != section.get("count") or len(runs) != section.get("runs"):
            raise MemoryFormatError(
                f"{directory}: manifest says {section.get('count')} success frames in {section.get('runs')} runs, "
                f"{RUNS} has {frames} in {len(runs)} runs"
            )
        sizes = [len(run.frames) for run in runs]
        tasks = [run.task for run, size in zip(runs, sizes, strict=True) for _ in range(size)]
        episodes = [run.episode for run, size in zip(runs, sizes, strict=True) for _ in range(size)]
        if isinstance(section.get("index"), dict):
            index = TaskIndexSet.read(directory, section["index"], tasks, episodes, dim=dim)
            return cls(
                index.exact_vectors(frames, dim),
                runs,
                dim=dim,
                index=index,
                offered=section.get("offered"),
                thinning=section.get("thinning"),
            )
        # written before per-task index files: one flat index of every frame, re-indexed here
        flat = read_index_file(directory / INDEX, count=frames)
        vectors = flat.reconstruct_n(0, flat.ntotal) if flat.ntotal else np.zeros((0, flat.d), np.float32)
        return cls(vectors, runs, dim=int(flat.d))


def _blank_frames(trajectory: Trajectory, view: str, frames: Sequence[Frame], blank: np.ndarray) -> Skipped:
    """What a run's blank frames cost the success memory (the whole view when its first frame is blank)."""
    where = Path(absolute_reference(frames[0].reference)).parent
    why = (
        f"its first frame is {BLANK_REASON}: the view is not in the success memory"
        if blank[0]
        else f"frame(s) {frame_ranges(np.flatnonzero(blank).tolist())} of {len(frames)} are {BLANK_REASON}"
    )
    return Skipped(where, f"{trajectory.key} view {view}: {why}", view)
