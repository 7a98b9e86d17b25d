"""FailureDetector: S_t per view is the brute-force task maximum; step API equals the batch run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from synthetic import write_episode

from robofailring import (
    CachedEncoder,
    FailureDetector,
    FailureMemory,
    FailureReport,
    load_dataset,
    load_encoder,
    load_trajectory,
)
from robofailring.detection import detector as detector_module
from robofailring.errors import EncoderMismatchError, UnknownTaskError
from robofailring.memory.pairs import pair_vectors


@pytest.fixture()
def memory_and_encoder(
    pixels_memory: FailureMemory, encoder: CachedEncoder
) -> tuple[FailureMemory, CachedEncoder]:
    return pixels_memory, encoder


def test_trace_equals_brute_force(
    memory_and_encoder: tuple[FailureMemory, CachedEncoder], tmp_path: Path
) -> None:
    memory, encoder = memory_and_encoder
    trajectory = load_trajectory(
        write_episode(tmp_path / "ep", "pick_cube", "grasp_wp2", length=7), task="pick_cube"
    )
    trace = FailureDetector(memory, encoder, delta=0.9, k=3).run(trajectory)
    raw = load_encoder("pixels")
    members = np.array([i for i, e in enumerate(memory.entries) if e.task == "pick_cube"])
    assert trace.length == 7 and trace.views == ["front", "overhead", "wrist"]
    for view in trace.views:
        embeddings = raw.encode([f.load() for f in trajectory.views[view]])
        queries = pair_vectors(np.repeat(embeddings[:1], 7, axis=0), embeddings, pairing="concat")
        expected = (queries @ memory.vectors[members].T).max(axis=1)
        np.testing.assert_allclose(trace.similarity[view], expected, atol=1e-5)
        assert all(n.entry.task == "pick_cube" for t in range(7) for n in trace.neighbors(view, t))
    fused = np.stack([trace.similarity[v] for v in trace.views]).max(axis=0) >= 0.9
    np.testing.assert_array_equal(trace.state, fused)
    assert trace.t_det == (int(np.argmax(fused)) if fused.any() else None)


def test_the_verdict_line_says_where_the_rule_fired_or_how_near_it_came(
    memory_and_encoder: tuple[FailureMemory, CachedEncoder], tmp_path: Path
) -> None:
    memory, encoder = memory_and_encoder
    trajectory = load_trajectory(
        write_episode(tmp_path / "ep", "pick_cube", "grasp_wp2", length=7, shift=2), task="pick_cube"
    )  # frames of no memory entry: its peak is below 1
    trace = FailureDetector(memory, encoder, delta=0.9, k=3).run(trajectory)
    fused = np.stack([trace.similarity[v] for v in trace.views]).max(axis=0)
    peak, at = float(fused.max()), int(fused.argmax())
    assert peak < 0.99
    below = trace.with_delta(peak + 0.01)
    assert (
        below.verdict()
        == f"no alarm (paper rule: peak S_t = {peak:.3f} at frame {at} < {below.threshold:.3f})"
    )
    fired = trace.with_delta(peak - 1e-3)
    t, view = fired.t_det, fired.detected_view
    assert t is not None and view is not None
    assert fired.verdict() == (
        f"FAILURE detected at frame {t}/7 in view {view} (paper rule: S_t = "
        f"{float(trace.similarity[view][t]):.3f} ≥ {peak - 1e-3:.3f})"
    )


@pytest.mark.parametrize("stride", [1, 2])
def test_chunks_score_as_one_batch_and_keep_only_what_is_asked(
    memory_and_encoder: tuple[FailureMemory, CachedEncoder],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    stride: int,
) -> None:
    memory, encoder = memory_and_encoder
    trajectory = load_trajectory(
        write_episode(tmp_path / "ep", "pick_cube", "grasp_wp2", length=11), task="pick_cube"
    )
    whole = FailureDetector(memory, encoder, k=3).run(trajectory, stride=stride)
    monkeypatch.setattr(detector_module, "CHUNK_FRAMES", 2)  # 11 frames: 6 or 3 chunks, the last short
    placed_rows: list[tuple[str, int]] = []

    def place(view: str, queries: np.ndarray) -> np.ndarray:
        placed_rows.append((view, len(queries)))
        return queries[:, :2] * 10.0

    chunked = FailureDetector(memory, encoder, k=3).run(
        trajectory, stride=stride, keep_queries=False, place=place
    )
    assert chunked.queries == {} and len(placed_rows) == 3 * -(-len(whole.scored_frames) // 2)
    for view in whole.views:
        np.testing.assert_allclose(
            chunked.similarity[view], whole.similarity[view], atol=1e-6, equal_nan=True
        )
        np.testing.assert_array_equal(chunked.neighbor_ids[view], whole.neighbor_ids[view])
        np.testing.assert_allclose(chunked.placed[view], whole.queries[view][:, :2] * 10.0, atol=1e-6)
    assert (
        chunked.t_det == whole.t_det and chunked.success_similarity.keys() == whole.success_similarity.keys()
    )


def test_detection_and_fusion(memory_and_encoder: tuple[FailureMemory, CachedEncoder]) -> None:
    memory, encoder = memory_and_encoder
    failure = next(
        t for t in load_dataset(memory.entries[0].start.rsplit("/", 2)[0]) if t.symbol == "wrong_object"
    )
    detector = FailureDetector(memory, encoder, delta=0.999, k=2)
    trace = detector.run(failure)  # its own entries are in memory: the last frame matches exactly
    raw = load_encoder("pixels")
    members = memory.vectors[[i for i, e in enumerate(memory.entries) if e.task == failure.task]]
    by_view = []
    for frames in failure.views.values():
        embeddings = raw.encode([f.load() for f in frames])
        queries = pair_vectors(np.repeat(embeddings[:1], len(frames), axis=0), embeddings, pairing="concat")
        by_view.append((queries @ members.T).max(axis=1))
    reached = np.flatnonzero(np.stack(by_view).max(axis=0) >= 0.999)  # the fused S_t reaches δ
    assert reached.size > 0 and trace.t_det == int(reached[0])
    assert trace.similarity[trace.detected_view][trace.length - 1] == pytest.approx(1.0, abs=1e-5)
    held_out = detector.run(failure, leave_one_out=True)
    assert all(
        memory.entries[i].episode != failure.episode
        for v in held_out.views
        for i in held_out.neighbor_ids[v].ravel()
    )
    assert held_out.similarity["front"][-1] < 0.99999
    # δ above every score never fires; δ at the max fires at its frame
    assert trace.with_delta(1.01).t_det is None
    peak = trace.max_similarity()
    assert trace.with_delta(float(peak.max())).t_det == int(np.argmax(peak))


def test_step_api_matches_run(
    memory_and_encoder: tuple[FailureMemory, CachedEncoder], tmp_path: Path
) -> None:
    memory, _ = memory_and_encoder
    trajectory = load_trajectory(
        write_episode(tmp_path / "ep", "push_cube", "slip_wp3", length=5), task="push_cube"
    )
    detector = FailureDetector(memory, load_encoder("pixels"), delta=0.95, k=4)
    trace = detector.run(trajectory)
    session = detector.session("push_cube")
    for t in range(trajectory.length):
        step = session.step({view: frames[t].load() for view, frames in trajectory.views.items()})
        assert step.t == t
        for view in trace.views:
            assert step.similarity[view] == pytest.approx(float(trace.similarity[view][t]), abs=1e-5)
            assert [n.index for n in step.neighbors[view]] == [n.index for n in trace.neighbors(view, t)]
        assert step.state == bool(trace.state[t])
    assert session.fired_at == trace.t_det


def test_report_from_detection(
    memory_and_encoder: tuple[FailureMemory, CachedEncoder], tmp_path: Path
) -> None:
    memory, encoder = memory_and_encoder
    trajectory = load_trajectory(write_episode(tmp_path / "ep", "pick_cube", "grasp_wp2"), task="pick_cube")
    trace = FailureDetector(memory, encoder, delta=-1.0, k=3).run(trajectory)
    assert trace.t_det == 0
    view = trace.detected_view
    assert view is not None
    report = FailureReport.from_neighbors(
        task="pick_cube",
        view=view,
        t_det=0,
        neighbors=trace.neighbors(view, 0),
        current_image=str(trajectory.views[view][0].path),
    )
    assert (
        len(report.items) == 3
        and report.items[0].description == memory.entries[report_index(trace, view)].description
    )
    messages = report.vlm_messages()
    assert messages[0]["role"] == "system" and "robotic failure analyst" in messages[0]["content"]
    assert '"failure": "The failure was caused by' in messages[1]["content"]
    images = [
        p["path"]
        for m in messages
        if isinstance(m["content"], list)
        for p in m["content"]
        if p["type"] == "image"
    ]
    assert images[0] == str(Path(report.items[0].start_image).resolve())
    assert images[-1] == str(Path(trajectory.views[view][0].path).resolve())
    assert messages[-1]["role"] == "assistant"
    markdown = report.to_markdown()
    assert "| 0 | pick_cube |" in markdown and "VLM prompt" in markdown
    assert report.to_dict()["neighbors"][0]["symbol"] == report.items[0].symbol


def report_index(trace: object, view: str) -> int:
    return int(trace.neighbor_ids[view][0, 0])  # type: ignore[attr-defined]


def test_errors(memory_and_encoder: tuple[FailureMemory, CachedEncoder], tmp_path: Path) -> None:
    memory, encoder = memory_and_encoder
    other = memory.__class__(memory.vectors, memory.entries, encoder="open_clip:ViT-B-32:openai")
    with pytest.raises(EncoderMismatchError):
        FailureDetector(other, encoder)
    detector = FailureDetector(memory, encoder)
    with pytest.raises(UnknownTaskError, match="'open_drawer'"):
        detector.session("open_drawer")
    trajectory = load_trajectory(write_episode(tmp_path / "ep", "pick_cube", None), task="open_drawer")
    with pytest.raises(UnknownTaskError, match="'open_drawer'"):
        detector.run(trajectory)
    assert detector.delta == 0.92  # the paper's default when the memory is not calibrated
