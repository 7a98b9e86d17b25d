"""The memory map laid out per view: failure types form the clusters, the panel's grid, and the cache's key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rfr_viz.panels.map import FRAME, PITCH, MapGrid
from rfr_viz.panels.umap import CACHE_FILE, fit_map, memory_map
from rfr_viz.panels.umap_layout import fit_map_2d, knn_purity
from robofailring.memory.failure import FailureMemory, MemoryEntry
from robofailring.memory.pairs import pair_vectors

VIEWS = ("front", "overhead", "wrist")
TASKS = ("pick_cube", "push_cube")
SYMBOLS = ("grasp_wp2", "slip_wp3", "rotation_x_wp1", "wrong_object")


def _unit(rows: np.ndarray) -> np.ndarray:
    return rows / np.linalg.norm(rows, axis=-1, keepdims=True)


def _sim_like_memory(episodes: int = 6, dim: int = 48) -> FailureMemory:
    """Pair vectors shaped like the simulator's: the first frame is set by the camera, the task and the
    episode's scene (strongly); the last frame adds the task's usual motion and the failure type's change."""
    rng = np.random.default_rng(5)
    view_part = 2.0 * _unit(rng.standard_normal((len(VIEWS), dim)))
    task_part = 1.0 * _unit(rng.standard_normal((len(TASKS), dim)))
    motion = 0.8 * _unit(rng.standard_normal((len(VIEWS), len(TASKS), dim)))
    change = 0.5 * _unit(rng.standard_normal((len(VIEWS), len(SYMBOLS), dim)))
    starts, ends, entries = [], [], []
    for t, task in enumerate(TASKS):
        for s, symbol in enumerate(SYMBOLS):
            for episode in range(episodes):
                scene = 1.5 * _unit(rng.standard_normal(dim))
                for v, view in enumerate(VIEWS):
                    start = view_part[v] + task_part[t] + scene
                    end = start + motion[v, t] + change[v, s] + 0.1 * _unit(rng.standard_normal(dim))
                    starts.append(start)
                    ends.append(end)
                    name = f"{task}_{symbol}_episode{episode}"
                    entries.append(MemoryEntry(task, symbol, name, view, "<array>", "<array>"))
    return FailureMemory(
        pair_vectors(np.array(starts), np.array(ends), pairing="concat"), entries, encoder="sim-like"
    )


def test_failure_types_not_cameras_form_the_clusters() -> None:
    memory = _sim_like_memory()
    symbols = np.array([entry.symbol for entry in memory.entries])
    views = np.array([entry.view for entry in memory.entries])
    one_map = fit_map_2d(memory.vectors).embedding  # the map before: one UMAP of the vectors
    assert knn_purity(one_map, views) > 0.95  # one island per camera …
    before = knn_purity(one_map, symbols)
    mapped = fit_map(memory)
    after = np.mean([knn_purity(mapped.maps[view].embedding, symbols[mapped.rows[view]]) for view in VIEWS])
    chance = 1 / len(SYMBOLS)
    assert before < chance + 0.15 and after > 0.9, (before, after)  # … now one cluster per failure type


def test_a_query_lands_in_its_own_view_among_its_failure_type() -> None:
    memory = _sim_like_memory()
    mapped = fit_map(memory)
    entry = 7
    view, task, symbol = memory.entries[entry].view, memory.entries[entry].task, memory.entries[entry].symbol
    placed = mapped.project(view, task, memory.vectors[entry : entry + 1])
    assert placed is not None
    view_map = mapped.maps[view]
    nearest = np.argsort(np.linalg.norm(view_map.embedding - placed, axis=1))[:5]
    assert [memory.entries[mapped.rows[view][i]].symbol for i in nearest] == [symbol] * 5


def test_the_cache_is_keyed_on_views_and_tasks_and_refits_older_caches(tmp_path: Path) -> None:
    memory = _sim_like_memory(episodes=2)
    fitted = memory_map(memory, directory=tmp_path)
    assert fitted.fitted and (tmp_path / CACHE_FILE).is_file()
    assert not memory_map(memory, directory=tmp_path).fitted
    renamed = [
        MemoryEntry(
            e.task,
            e.symbol,
            e.episode,
            {"front": "wrist", "wrist": "front"}.get(e.view, e.view),
            e.start,
            e.end,
        )
        for e in memory.entries
    ]
    swapped = FailureMemory(memory.vectors, renamed, encoder=memory.encoder)
    again = memory_map(swapped, directory=tmp_path)  # same vectors, other views: not the cached maps
    assert again.fitted and again.views == ["wrist", "overhead", "front"]
    # a version-1 cache (one map of all vectors) is refit and overwritten
    np.savez(
        tmp_path / CACHE_FILE, version=np.int64(1), digest=np.str_(fitted.digest), method=np.str_("umap")
    )
    assert memory_map(memory, directory=tmp_path).fitted
    assert not memory_map(memory, directory=tmp_path).fitted


@pytest.mark.parametrize(
    ("views", "columns", "rows", "in_cell"),
    [(1, 1, 1, False), (2, 2, 1, False), (3, 2, 2, True), (4, 2, 2, False), (5, 3, 2, True)],
)
def test_the_map_grid_places_maps_and_legend_inside_the_bounds(
    views: int, columns: int, rows: int, in_cell: bool
) -> None:
    grid = MapGrid(views=views, legend_entries=7)
    assert (grid.columns, grid.rows, grid.legend_in_cell) == (columns, rows, in_cell)
    (left, right), (top, bottom) = grid.bounds()
    centres = np.array([grid.offset(position) for position in range(views)])
    assert len({tuple(c) for c in centres}) == views
    assert np.all(centres[:, 0] - FRAME >= left) and np.all(centres[:, 0] + FRAME <= right)
    assert np.all(centres[:, 1] + FRAME <= bottom) and np.all(centres[:, 1] - FRAME >= top)
    legend = grid.legend_positions()
    assert legend.shape == (7, 2) and len({tuple(p) for p in legend}) == 7
    assert np.all((legend[:, 0] >= left) & (legend[:, 0] <= right))
    assert np.all((legend[:, 1] >= top) & (legend[:, 1] <= bottom))
    for centre in centres:  # no legend entry sits on a map
        inside = np.all(np.abs(legend - centre) < FRAME, axis=1)
        assert not inside.any()
    assert PITCH > 2 * FRAME  # the maps' boxes do not touch
