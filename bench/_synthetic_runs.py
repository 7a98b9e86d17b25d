"""Synthetic success memories for bench_scale.py: smooth trajectories on the unit sphere, by task.

A frame embedding is f_t = norm(shared + task centre + view offset + run offset + path(s_t) + noise):
the shared part stands for the robot and table every camera sees, the path is a smooth curve per
task (a few Fourier terms) walked at a per-run speed, so consecutive frames of a run are close
and runs of one task resemble each other. The memory vector is the success memory's
u_t = norm([f_0 ‖ f_t]) (memory.pair_vectors). `describe()` prints the cosines this gives.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from robofailring.memory.pairs import pair_vectors

HALF = 512  # the frame encoder's dimension; memory vectors are 2 × HALF = 1024-d
VIEWS = 3
FRAMES = 600  # 20 s at 30 fps per run and view
TERMS = 8  # Fourier terms of a task's path


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector, axis=-1, keepdims=True)


@dataclass(frozen=True)
class TaskModel:
    centre: np.ndarray  # (HALF,)
    views: np.ndarray  # (VIEWS, HALF)
    path: np.ndarray  # (2 * TERMS, HALF)


_SHARED = _unit(np.random.default_rng(7).standard_normal(HALF)).astype(np.float32)


def task_model(task: int) -> TaskModel:
    rng = np.random.default_rng(1000 + task)
    scale = 1.0 / np.sqrt(HALF)
    terms = np.repeat(1.0 / np.arange(1, TERMS + 1), 2)[:, None]
    return TaskModel(
        centre=0.8 * _unit(rng.standard_normal(HALF)),
        views=0.5 * _unit(rng.standard_normal((VIEWS, HALF))),
        path=0.9 * scale * terms * rng.standard_normal((2 * TERMS, HALF)),
    )


def run_frames(
    model: TaskModel, seed: int, view: int, *, frames: int = FRAMES, deviate: float = 0.0
) -> np.ndarray:
    """Frame embeddings (frames, HALF) of one run's view; `deviate` > 0 bends the run's second half away."""
    rng = np.random.default_rng(seed)
    progress = np.linspace(0.0, 1.0, frames) ** np.exp(rng.normal(0.0, 0.15))
    k = np.arange(1, TERMS + 1)
    basis = np.concatenate(
        [np.cos(np.pi * progress[:, None] * k), np.sin(np.pi * progress[:, None] * k)], axis=1
    )
    offset = 0.3 * _unit(rng.standard_normal(HALF))
    noise = 0.1 * rng.standard_normal((frames, HALF)) / np.sqrt(HALF)
    frame = 1.6 * _SHARED + model.centre + model.views[view] + offset + basis @ model.path + noise
    if deviate:
        away = deviate * _unit(rng.standard_normal(HALF))
        frame += np.clip(2 * progress - 1, 0, None)[:, None] * away
    return _unit(frame).astype(np.float32)


def run_vectors(model: TaskModel, seed: int, view: int, **options: float) -> np.ndarray:
    frames = run_frames(model, seed, view, **options)  # type: ignore[arg-type]
    return pair_vectors(np.repeat(frames[:1], len(frames), axis=0), frames, pairing="concat")


def task_memory(task: int, count: int) -> Iterator[tuple[np.ndarray, int]]:
    """Chunks of (vectors, run number) of one task's success memory until `count` entries."""
    made, run = 0, 0
    while made < count:
        for view in range(VIEWS):
            vectors = run_vectors(task_model(task), seed=task * 1_000_003 + run, view=view)
            vectors = vectors[: count - made]
            made += len(vectors)
            yield vectors, run
            if made >= count:
                return
        run += 1


def held_out_steps(task: int, steps: int, *, deviate: float) -> np.ndarray:
    """(steps, VIEWS, 1024) queries from runs not in the memory, at random frames."""
    rng = np.random.default_rng(5000 + task)
    out = np.empty((steps, VIEWS, 2 * HALF), np.float32)
    model = task_model(task)
    for step in range(steps):
        seed = 10_000_000 + task * 100_000 + step
        frame = int(rng.integers(0, FRAMES))
        for view in range(VIEWS):
            out[step, view] = run_vectors(model, seed, view, deviate=deviate)[frame]
    return out


def describe() -> str:
    """Cosines between frames and runs: consecutive, same run ends, two runs, two tasks."""
    a = run_vectors(task_model(0), 1, 0)
    b = run_vectors(task_model(0), 2, 0)
    c = run_vectors(task_model(1), 3, 0)
    return (
        f"synthetic runs: cos(u_t, u_t+1) median {np.median((a[1:] * a[:-1]).sum(1)):.4f}, "
        f"cos(u_0, u_T) {float(a[0] @ a[-1]):.3f}, same frame of two runs {np.median((a * b).sum(1)):.3f}, "
        f"two tasks {np.median((a * c).sum(1)):.3f}"
    )
