"""rfr_viz: recordings written, then read back with RrdReader and checked value by value (docs/recording.md, "The recording layout")."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Sequence
from datetime import timedelta
from pathlib import Path

import cv2
import numpy as np
import pytest
from rrd import batches, entity_paths, properties, reader, rows, static_value
from synthetic import write_episode
from typer.testing import CliRunner

import rfr_viz.panels.map as map_panel
import rfr_viz.panels.umap_layout as umap_layout
import rfr_viz.recordings.replay as record_module
from rfr_viz.cli.app import app
from rfr_viz.jobs.recorded import Recordings
from rfr_viz.jobs.replay import ReplayConfig, recording_name, replay
from rfr_viz.panels.images import reference_jpeg
from rfr_viz.panels.neighbors import changes
from rfr_viz.panels.umap import CACHE_FILE, MemoryMap, fit_map, memory_map
from rfr_viz.paths import APPLICATION_ID, REPLAY, DetectorPaths, camera
from rfr_viz.recordings.replay import compare_recording, record_replay
from rfr_viz.viewer.binary import viewer_binary
from rfr_viz.viewer.control import open_command
from rfr_viz.viewer.rrd import verify_recording
from robofailring import (
    CachedEncoder,
    DetectionTrace,
    FailureDetector,
    FailureMemory,
    Trajectory,
    load_dataset,
    load_trajectory,
)
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.encoders.placement import EncoderPlacement
from robofailring.memory.failure import MemoryEntry
from robofailring.memory.pairs import pair_vectors

VIEWS = ["front", "overhead", "wrist"]


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def memory(pixels_memory_dir: Path, aha_dataset: Path) -> FailureMemory:
    return FailureMemory.load(pixels_memory_dir, trusted=[aha_dataset])  # its images: the AHA data, named


@pytest.fixture(scope="module")
def mapped(memory: FailureMemory, pixels_memory_dir: Path) -> MemoryMap:
    return memory_map(memory, directory=pixels_memory_dir)


@pytest.fixture(scope="module")
def trajectory(tmp_path_factory: pytest.TempPathFactory) -> Trajectory:
    folder = tmp_path_factory.mktemp("episodes") / "pick_cube_grasp_wp2_episode9"
    return load_trajectory(write_episode(folder, "pick_cube", "grasp_wp2", length=9))


@pytest.fixture(scope="module")
def trace(memory: FailureMemory, encoder: CachedEncoder, trajectory: Trajectory) -> DetectionTrace:
    """δ set to the median of max-over-views S_t, so the detector fires part-way through."""
    first = FailureDetector(memory, encoder, k=3).run(trajectory)
    return first.with_delta(float(np.median(first.max_similarity())))


@pytest.fixture(scope="module")
def recording(
    trajectory: Trajectory, trace: DetectionTrace, mapped: MemoryMap, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    return record_replay(
        trajectory, trace, out=tmp_path_factory.mktemp("rec") / "replay.rrd", memory_map=mapped
    )


# ------------------------------------------------------------------ the contract
def test_every_entity_of_the_contract_is_there(recording: Path, trace: DetectionTrace) -> None:
    paths = entity_paths(recording)
    expected = {camera(v) for v in VIEWS} | {REPLAY.score(v, "paper") for v in VIEWS}
    expected |= {
        REPLAY.threshold("paper"),
        REPLAY.state,
        REPLAY.event,
        REPLAY.map_root,
        REPLAY.map_legend,
        REPLAY.report,
    }
    expected |= {path for v in VIEWS for path in (REPLAY.umap(v), REPLAY.umap_query(v), REPLAY.umap_frame(v))}
    expected |= {REPLAY.umap_title(v) for v in VIEWS}
    expected |= {
        REPLAY.neighbor(v, r, p) for v in VIEWS for r in range(trace.k) for p in ("start", "end", "info")
    }
    assert expected <= paths, sorted(expected - paths)
    read = reader(recording)
    assert [entry.application_id for entry in read.recordings()] == [APPLICATION_ID]
    assert read.blueprints(), "the blueprint is saved inside the recording"
    # never raw pixels: every image is an EncodedImage JPEG
    for chunk in read.stream().to_chunks():
        names = chunk.to_record_batch().schema.names
        assert not any(name.startswith("Image:") for name in names), chunk.entity_path


def test_one_jpeg_camera_row_per_frame_per_view(recording: Path, trajectory: Trajectory) -> None:
    for view in VIEWS:
        blobs = rows(recording, camera(view), "EncodedImage:blob")
        assert [frame for frame, _ in blobs] == list(range(trajectory.length))
        media = rows(recording, camera(view), "EncodedImage:media_type")
        assert {value[0] for _, value in media} == {"image/jpeg"}
        for frame, blob in blobs[::4]:
            data = bytes(blob[0])
            assert data[:3] == b"\xff\xd8\xff"
            decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]
            source = trajectory.views[view][frame].load()
            assert decoded.shape == source.shape
            assert float(np.abs(decoded.astype(int) - source.astype(int)).mean()) < 6.0


def test_scores_delta_state_and_timelines_equal_the_trace(recording: Path, trace: DetectionTrace) -> None:
    frames = list(range(trace.length))
    for view in VIEWS:
        scores = rows(recording, REPLAY.score(view, "paper"), "Scalars:scalars")
        assert [frame for frame, _ in scores] == frames
        np.testing.assert_allclose([value[0] for _, value in scores], trace.similarity[view], atol=1e-6)
    delta = rows(recording, REPLAY.threshold("paper"), "Scalars:scalars")
    assert [frame for frame, _ in delta] == frames
    np.testing.assert_allclose([value[0] for _, value in delta], trace.delta)
    state = [value[0] for _, value in rows(recording, REPLAY.state, "Scalars:scalars")]
    np.testing.assert_array_equal(state, trace.state.astype(float))
    assert trace.t_det is not None and 0 < trace.t_det < trace.length
    assert state.index(1.0) == trace.t_det and state[trace.t_det - 1] == 0.0
    # the "time" timeline is frame / fps (10 fps when the data does not say)
    times = {}
    for batch in batches(recording, REPLAY.score("front", "paper")):
        if "time" in batch.schema.names:
            times.update(
                zip(batch.column("frame").to_pylist(), batch.column("time").to_pylist(), strict=True)
            )
    assert times[5] == timedelta(seconds=0.5)


def test_detection_event_report_and_properties(recording: Path, trace: DetectionTrace) -> None:
    events = rows(recording, REPLAY.event, "TextLog:text")
    assert [frame for frame, _ in events] == [trace.t_det]
    text = events[0][1][0]
    view = trace.detected_view
    assert view is not None and f"in view {view}" in text
    top = trace.neighbors(view, trace.t_det)[0]
    assert f"S_t = {top.similarity:.3f}" in text and top.entry.symbol in text
    reports = rows(recording, REPLAY.report, "TextDocument:text")
    assert [frame for frame, _ in reports] == [0, trace.t_det]
    assert "Failure report" in reports[1][1][0] and "VLM prompt" in reports[1][1][0]
    assert "![" not in reports[1][1][0]  # image links are plain text: the viewer must not fetch files
    found = properties(recording)
    assert found["task"] == "pick_cube" and found["label"] == "grasp_wp2" and found["outcome"] == "failure"
    assert found["encoder"] == trace.encoder and found["k"] == trace.k and found["L"] == trace.length
    assert found["t_det"] == trace.t_det and found["delta"] == pytest.approx(trace.delta)
    assert found["map"] == "umap"


def test_neighbour_images_are_logged_only_when_they_change(recording: Path, trace: DetectionTrace) -> None:
    for view in VIEWS:
        ids = trace.neighbor_ids[view]
        expected = changes(ids)
        assert len(expected) < ids.size  # the fixture's neighbours do stay put for a while
        for rank in range(trace.k):
            want = [(t, index) for r, t, index in expected if r == rank]
            for part in ("start", "end"):
                logged = rows(recording, REPLAY.neighbor(view, rank, part), "EncodedImage:blob")
                assert [frame for frame, _ in logged] == [t for t, _ in want]
                for (_, blob), (_, index) in zip(logged, want, strict=True):
                    entry = trace.memory.entries[index]
                    reference = entry.start if part == "start" else entry.end
                    assert bytes(blob[0]) == reference_jpeg(reference, trace.memory.image_roots)
            info = rows(recording, REPLAY.neighbor(view, rank, "info"), "TextDocument:text")
            assert (
                {t for t, _ in want} <= {frame for frame, _ in info} <= {t for t, _ in want} | {trace.t_det}
            )
            first = trace.memory.entries[want[0][1]]
            assert first.symbol in info[0][1][0] and first.description in info[0][1][0]


def test_rerun_rrd_verify_passes(recording: Path) -> None:
    result = subprocess.run(
        [str(viewer_binary()), "rrd", "verify", str(recording)],
        env={**os.environ, "CI": "1"},
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    corrupt = recording.with_name("corrupt.rrd")
    corrupt.write_bytes(recording.read_bytes()[:2000])
    with pytest.raises(ValueError, match="not a valid recording"):
        verify_recording(corrupt)


def test_each_run_is_a_new_recording_id(
    trajectory: Trajectory, trace: DetectionTrace, mapped: MemoryMap, tmp_path: Path
) -> None:
    first = record_replay(trajectory, trace, out=tmp_path / "a.rrd", memory_map=mapped)
    second = record_replay(trajectory, trace, out=tmp_path / "b.rrd", memory_map=mapped)
    ids = [reader(path).recordings()[0].recording_id for path in (first, second)]
    assert ids[0] != ids[1]


def test_jpeg_sources_pass_through_unchanged(
    memory: FailureMemory, encoder: CachedEncoder, mapped: MemoryMap, tmp_path: Path
) -> None:
    folder = tmp_path / "jpeg_episode"
    for view in ("front", "wrist"):
        (folder / view).mkdir(parents=True)
        for t in range(4):
            image = np.full((32, 32, 3), 40 * t + 20 * len(view), np.uint8)
            cv2.imwrite(str(folder / view / f"{t}.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    trajectory = load_trajectory(folder, task="push_cube")
    trace = FailureDetector(memory, encoder, k=2).run(trajectory)
    out = record_replay(trajectory, trace, out=tmp_path / "jpeg.rrd", memory_map=mapped, fps=4.0)
    for view in ("front", "wrist"):
        logged = rows(out, camera(view), "EncodedImage:blob")
        assert [bytes(blob[0]) for _, blob in logged] == [
            (folder / view / f"{t}.jpg").read_bytes() for t in range(4)
        ]
    assert trace.t_det is None and properties(out)["t_det"] == -1 and properties(out)["fps"] == 4.0


# ------------------------------------------------------------------ atomic writes
def test_a_failed_write_leaves_nothing_under_the_final_name(
    trajectory: Trajectory,
    trace: DetectionTrace,
    mapped: MemoryMap,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(record_module, "log_detector", broken)
    out = tmp_path / "recs" / "replay.rrd"
    with pytest.raises(RuntimeError, match="disk on fire"):
        record_replay(trajectory, trace, out=out, memory_map=mapped)
    assert not out.parent.exists()  # nothing under the final name, nor the folder made for it
    # an earlier recording under that name survives a failed rewrite untouched
    monkeypatch.undo()
    record_replay(trajectory, trace, out=out, memory_map=mapped)
    before = out.read_bytes()
    monkeypatch.setattr(record_module, "log_detector", broken)
    with pytest.raises(RuntimeError):
        record_replay(trajectory, trace, out=out, memory_map=mapped)
    assert out.read_bytes() == before and [p.name for p in out.parent.iterdir()] == ["replay.rrd"]


# ------------------------------------------------------------------ the memory map
def test_map_is_fitted_once_and_cached_beside_the_memory(
    memory: FailureMemory,
    pixels_memory_dir: Path,
    aha_dataset: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    directory = tmp_path / "memory"
    memory.save(directory)
    fits: list[int] = []
    real_fit = umap_layout._umap_embedding

    def counting(vectors: np.ndarray, n_neighbors: int) -> np.ndarray:
        fits.append(len(vectors))
        return real_fit(vectors, n_neighbors)

    monkeypatch.setattr(umap_layout, "_umap_embedding", counting)
    config = ReplayConfig(
        data=DataSelection(aha_dataset),
        detector=DetectorConfig(
            memory=directory, placement=EncoderPlacement(cache_dir=tmp_path / "embeddings")
        ),
        recordings=Recordings(
            out=tmp_path / "recs", trajectories=("pick_cube/pick_cube_grasp_wp2_episode0",)
        ),
    )
    first = replay(config)
    cache = directory / CACHE_FILE
    per_view = [len(memory) // 3] * 3  # one UMAP per view
    assert fits == per_view and cache.is_file()
    stamp = cache.stat().st_mtime_ns
    second = replay(config)
    assert fits == per_view, "the second replay does no UMAP work"
    assert cache.stat().st_mtime_ns == stamp
    assert len(first.recordings) == len(second.recordings) == 1
    cached = memory_map(memory, directory=directory)
    assert not cached.fitted and cached.method == "umap" and cached.views == VIEWS
    for view, view_map in cached.maps.items():
        assert view_map.n_neighbors == len(memory) // 3 - 1  # clamped to the view's entries
        # each map spans [-1, 1]² and a memory vector is placed near its own entry, in its view's map
        assert np.abs(view_map.embedding).max() == pytest.approx(1.0, abs=1e-5)
        placed = np.concatenate(
            [_placed(cached, view, memory.entries[i].task, memory.vectors[i]) for i in cached.rows[view]]
        )
        # against every entry's point: its own is nearer than most (a broken projection ranks it at random)
        distances = np.linalg.norm(placed[:, None, :] - view_map.embedding[None, :, :], axis=2)
        own_rank = (distances < np.diag(distances)[:, None]).sum(axis=1) / (len(placed) - 1)
        assert np.median(own_rank) < 0.25 and np.diag(distances).mean() < 0.5 * distances.mean()
    assert cached.project("side", "pick_cube", memory.vectors[:2]) is None  # the memory has no such view
    # a changed memory does not reuse a stale map
    other = FailureMemory(memory.vectors[:18], memory.entries[:18], encoder=memory.encoder)
    assert memory_map(other, directory=directory).fitted and len(fits) == 6


def _placed(mapped: MemoryMap, view: str, task: str, queries: np.ndarray) -> np.ndarray:
    placed = mapped.project(view, task, queries)
    assert placed is not None, f"the memory has a map of {view}"
    return placed


def _tiny_memory(count: int) -> FailureMemory:
    rng = np.random.default_rng(count)
    vectors = pair_vectors(rng.standard_normal((count, 8)), rng.standard_normal((count, 8)), pairing="concat")
    entries = [
        MemoryEntry(
            "pick_cube", ("slip_wp3", "grasp_wp2")[i % 2], f"episode{i}", "front", "<array>", "<array>"
        )
        for i in range(count)
    ]
    return FailureMemory(vectors, entries, encoder="tiny")


def test_tiny_memories_clamp_neighbours_or_fall_back_to_pca(tmp_path: Path) -> None:
    five = fit_map(_tiny_memory(5))
    assert five.method == "umap" and five.maps["front"].n_neighbors == 4
    assert five.maps["front"].embedding.shape == (5, 2)
    three = _tiny_memory(3)
    pca = memory_map(three, directory=tmp_path)
    assert pca.method == "pca" and "PCA" in pca.note and "too few for UMAP" in pca.note
    np.testing.assert_allclose(
        pca.project("front", "pick_cube", three.vectors), pca.maps["front"].embedding, atol=1e-5
    )
    again = memory_map(three, directory=tmp_path)
    assert not again.fitted and again.method == "pca"
    np.testing.assert_allclose(
        again.project("front", "pick_cube", three.vectors), pca.maps["front"].embedding, atol=1e-5
    )
    one = fit_map(_tiny_memory(1))
    assert one.method == "pca" and np.isfinite(one.maps["front"].embedding).all()


def test_map_points_classes_labels_and_moving_queries(
    recording: Path, trace: DetectionTrace, mapped: MemoryMap
) -> None:
    """One map per view, side by side: each holds that view's entries only, and that view's query moves in it."""
    entries = trace.memory.entries
    expected = {"grasp_wp2": 3, "rotation_x_wp1": 1, "wrong_object": 7}
    assert mapped.views == VIEWS and mapped.size == len(entries)
    offsets = []
    for view in VIEWS:
        rows_of_view = mapped.rows[view]
        assert {entries[i].view for i in rows_of_view} == {view}
        positions = static_value(recording, REPLAY.umap(view), "Points2D:positions")
        np.testing.assert_allclose(positions, mapped.maps[view].embedding, atol=1e-6)
        classes = static_value(recording, REPLAY.umap(view), "Points2D:class_ids")
        assert classes == [expected[entries[i].symbol] for i in rows_of_view]
        labels = static_value(recording, REPLAY.umap(view), "Points2D:labels")
        first = entries[rows_of_view[0]]
        assert labels[0] == f"{first.task} · {first.symbol} · {first.view} · {first.episode}"
        offsets.append(tuple(static_value(recording, REPLAY.umap(view), "Transform3D:translation")[0]))
        title = static_value(recording, REPLAY.umap_title(view), "Points2D:labels")
        assert title == [f"{view} · {len(rows_of_view)} entries"]
        moving = rows(recording, REPLAY.umap_query(view), "Points2D:positions")
        assert [frame for frame, _ in moving] == list(range(trace.length))
        np.testing.assert_allclose(
            [value[0] for _, value in moving],
            mapped.project(view, trace.task, trace.queries[view]),
            atol=1e-5,
        )
    grid = [(0.0, 0.0, 0.0), (map_panel.PITCH, 0.0, 0.0), (0.0, map_panel.PITCH + map_panel.TITLE, 0.0)]
    np.testing.assert_allclose(offsets, grid, atol=1e-6)  # two maps on top, the third below, float32
    legend = static_value(recording, REPLAY.map_legend, "Points2D:labels")
    assert legend == ["rotation (12)", "grasp (12)", "wrong_object (12)"]
    context = static_value(recording, REPLAY.map_root, "AnnotationContext:context")
    info = {item["class_id"]: item["class_description"]["info"] for item in context[0]}
    assert (
        info[1]["label"] == "rotation" and info[3]["label"] == "grasp" and info[7]["label"] == "wrong_object"
    )
    assert info[1]["color"] == 0xE65546FF  # fixed colours: rotation is always (230, 85, 70)
    assert len({item["color"] for item in info.values()}) == len(info)


# ------------------------------------------------------------------ encoder comparison
class ChannelMeans:
    """A second, different encoder: per-channel means on a 16x16 grid, projected to 64-d."""

    identity = "means-v1-64d"
    dim = 64

    def __init__(self) -> None:
        self.projection = np.random.default_rng(7).standard_normal((16 * 16 * 3, 64)).astype(np.float32)

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        small = np.stack([cv2.resize(image, (16, 16), interpolation=cv2.INTER_AREA) for image in images])
        flat = small.reshape(len(images), -1).astype(np.float32) / 255.0
        flat -= flat.mean(axis=1, keepdims=True)
        vectors = flat @ self.projection
        return vectors / np.linalg.norm(vectors, axis=1, keepdims=True)


def test_comparison_recording_has_every_encoder_under_its_slug(
    aha_dataset: Path, memory: FailureMemory, trace: DetectionTrace, trajectory: Trajectory, tmp_path: Path
) -> None:
    means = CachedEncoder(ChannelMeans(), enabled=False)  # type: ignore[arg-type]
    other_memory, _ = FailureMemory.build(load_dataset(aha_dataset), means)
    other = FailureDetector(other_memory, means, delta=0.5, k=2).run(trajectory)
    out = compare_recording(trajectory, {"pixels": trace, "means": other}, out=tmp_path / "cmp.rrd")
    paths = entity_paths(out)
    for slug, each in (("pixels", trace), ("means", other)):
        encoder_paths = DetectorPaths.for_encoder(slug)
        for view in VIEWS:
            scores = rows(out, encoder_paths.score(view, "paper"), "Scalars:scalars")
            np.testing.assert_allclose([v[0] for _, v in scores], each.similarity[view], atol=1e-6)
        assert {
            encoder_paths.threshold("paper"),
            encoder_paths.state,
            encoder_paths.umap("front"),
            encoder_paths.report,
        } <= paths
        events = rows(out, encoder_paths.event, "TextLog:text")
        assert [frame for frame, _ in events] == ([each.t_det] if each.t_det is not None else [])
        group = properties(out, slug)
        assert group["encoder"] == each.encoder and group["delta"] == pytest.approx(each.delta)
    assert not any(path.startswith(("/score", "/detection", "/neighbors", "/memory")) for path in paths)
    for view in VIEWS:
        assert [frame for frame, _ in rows(out, camera(view), "EncodedImage:blob")] == list(
            range(trajectory.length)
        )
    assert properties(out)["encoders"] == "pixels, means"


# ------------------------------------------------------------------ command line
runner = CliRunner()


def test_cli_replay_and_compare(aha_dataset: Path, pixels_memory_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "recordings"
    key = "push_cube/push_cube_rotation_x_wp1_episode1"
    result = runner.invoke(
        app,
        [
            "replay",
            str(aha_dataset),
            "--memory",
            str(pixels_memory_dir),
            "--out",
            str(out),
            "--trajectory",
            key,
            "--k",
            "2",
            "--delta",
            "0.99",
            "--leave-one-out",
            "--cache-dir",
            str(tmp_path / "cache"),
        ],
    )
    assert result.exit_code == 0, result.output
    recorded = out / "push_cube__push_cube_rotation_x_wp1_episode1.rrd"
    assert recorded.is_file() and f"rerun {recorded}" in result.output
    found = properties(recorded)
    assert found["k"] == 2 and found["delta"] == 0.99 and found["label"] == "rotation_x_wp1"
    # under the recording's path, one line says what its detector did, as the recording has it
    said = result.output.splitlines()[
        result.output.splitlines().index(f"  {open_command(recorded)}") + 1
    ].strip()
    if found["t_det"] is None:
        assert said.startswith("no alarm (paper rule: peak S_t = ") and said.endswith("< 0.990)"), said
    else:
        assert (
            said.startswith(f"FAILURE detected at frame {found['t_det']}/")
            and f"view {found['detected_view']}" in said
        )
    neighbours = rows(recorded, REPLAY.neighbor("front", 0, "info"), "TextDocument:text")
    assert neighbours and all("push_cube_rotation_x_wp1_episode1" not in text[0] for _, text in neighbours)
    # one episode folder, task given on the command line
    episode = write_episode(tmp_path / "an_episode", "pick_cube", None, length=5, views=("front", "side"))
    single = runner.invoke(
        app,
        [
            "replay",
            str(episode),
            "--memory",
            str(pixels_memory_dir),
            "--task",
            "pick_cube",
            "--out",
            str(out),
        ],
    )
    assert single.exit_code == 0, single.output
    assert (out / "pick_cube__an_episode.rrd").is_file()
    unknown = runner.invoke(
        app,
        [
            "replay",
            str(episode),
            "--memory",
            str(pixels_memory_dir),
            "--task",
            "open_door",
            "--out",
            str(out),
        ],
    )
    assert unknown.exit_code == 2 and "open_door" in unknown.output
    # two memories -> one comparison recording per trajectory
    arguments = [
        "compare",
        str(episode),
        "--memory",
        str(pixels_memory_dir),
        "--memory",
        str(pixels_memory_dir),
    ]
    arguments += ["--task", "pick_cube", "--out", str(out), "--delta", "0.9", "--delta", "0.95"]
    compared = runner.invoke(app, arguments)
    assert compared.exit_code == 0, compared.output
    comparison = out / "pick_cube__an_episode__pixels-vs-pixels-2.rrd"
    assert (
        properties(comparison, "pixels")["delta"] == 0.9
        and properties(comparison, "pixels-2")["delta"] == 0.95
    )
    assert {"/pixels/score/front/paper", "/pixels-2/score/side/paper"} <= entity_paths(comparison)


def test_recording_names_are_flat_and_safe(trajectory: Trajectory) -> None:
    assert recording_name(trajectory) == "pick_cube__pick_cube_grasp_wp2_episode9.rrd"
    maniskill = Trajectory(task="PickCube", episode="3/0_grasp_s1", views={})
    named = recording_name(maniskill, "__a-vs-b")
    assert named.startswith("PickCube__3_0_grasp_s1~") and named.endswith("__a-vs-b.rrd")
    # `/` became `_`, so a digest keeps it apart from an episode really named `3_0_grasp_s1`
    assert named != recording_name(Trajectory(task="PickCube", episode="3_0/grasp_s1", views={}), "__a-vs-b")


def test_large_memories_label_only_the_replayed_tasks_points(monkeypatch: pytest.MonkeyPatch) -> None:
    entries = [
        MemoryEntry(task, "slip_wp3", f"episode{i}", "front", "s.png", "e.png")
        for i, task in enumerate(["pick_cube", "push_cube"] * 3)
    ]
    assert all(map_panel.map_labels(entries, task="pick_cube"))
    monkeypatch.setattr(map_panel, "LABELLED_ENTRIES_MAX", 4)
    labels = map_panel.map_labels(entries, task="pick_cube")
    assert labels[0] == "pick_cube · slip_wp3 · front · episode0" and labels[1] == ""
    assert [bool(label) for label in labels] == [True, False] * 3


def test_a_view_too_short_to_detect_is_left_out_and_said_so(
    memory: FailureMemory, encoder: CachedEncoder, mapped: MemoryMap, tmp_path: Path
) -> None:
    folder = write_episode(tmp_path / "short", "pick_cube", "slip_wp3", length=5)
    for frame in sorted((folder / "wrist").iterdir())[1:]:
        frame.unlink()
    trajectory = load_trajectory(folder, task="pick_cube")
    trace = FailureDetector(memory, encoder, k=2).run(trajectory)
    out = record_replay(trajectory, trace, out=tmp_path / "short.rrd", memory_map=mapped)
    paths = entity_paths(out)
    assert (
        camera("front") in paths
        and camera("wrist") not in paths
        and REPLAY.score("wrist", "paper") not in paths
    )
    assert properties(out)["skipped_views"] == "wrist" and properties(out)["views"] == "front, overhead"
