"""The neighbour panel of a dense memory shows the moment of the past failure that matches, read back from a
real recording; the paper's memory says "end of the run"; the recording says which memory it used."""

from __future__ import annotations

from pathlib import Path

from rrd import properties, rows, static_value
from synthetic import repeated_failure_memory

from rfr_viz.panels.images import reference_jpeg
from rfr_viz.paths import REPLAY
from rfr_viz.recordings.replay import record_replay
from robofailring import CachedEncoder, FailureDetector, load_encoder
from robofailring.memory.image_roots import ImageRoots

LENGTH = 8
ONSET = 2


def _recording(root: Path, failure_frames: str) -> Path:
    """A new grasp failure whose frames are those of the memory's episode 0, replayed against a memory of
    `failure_frames` (K = 2)."""
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=root / "cache")
    memory, trajectory = repeated_failure_memory(
        root, encoder, length=LENGTH, onset=ONSET, failure_frames=failure_frames
    )
    trace = FailureDetector(memory, encoder, k=2, rule="paper").run(trajectory)
    return record_replay(trajectory, trace.with_delta(1.0 - 1e-5), out=root / "replay.rrd")


def test_the_dense_panel_names_the_frame_it_matched(tmp_path: Path) -> None:
    recording = _recording(tmp_path, "dense")
    info = dict(rows(recording, REPLAY.neighbor("front", 0, "info"), "TextDocument:text"))
    ends = dict(rows(recording, REPLAY.neighbor("front", 0, "end"), "EncodedImage:blob"))
    # from the onset on, each frame's nearest entry is that very frame of episode 0, shown with its number
    for t in range(ONSET, LENGTH):
        text = info[t][0]
        assert "pick_cube_grasp_wp2_episode0" in text and "cos **1.000**" in text
        moment = "end of the run" if t == LENGTH - 1 else f"{round(100 * t / LENGTH)} %"
        assert f"matched: frame {t} of {LENGTH} ({moment})" in text
        shown = ends[max(frame for frame in ends if frame <= t)]  # logged when the neighbour changed
        image = tmp_path / "data" / "pick_cube_grasp_wp2_episode0" / f"front_{t}.png"
        assert bytes(shown[0]) == reference_jpeg(
            str(image), ImageRoots.of(tmp_path)
        )  # beside it, that frame's
    log = rows(recording, REPLAY.neighbor("front", 0, "info"), "TextLog:text")
    assert any(f"frame {ONSET} of {LENGTH}" in text[0] for _, text in log)
    assert properties(recording)["failure_frames"] == "dense"
    # every dense entry is a point of its view's map, its hover label naming its frame
    labels = static_value(recording, REPLAY.umap("front"), "Points2D:labels")
    assert len(labels) == 2 * (LENGTH - ONSET)  # two failure runs, frames 2-7 each (all differ: none thinned)
    assert "pick_cube · grasp_wp2 · front · pick_cube_grasp_wp2_episode0 · frame 2/8" in labels


def test_the_papers_panel_says_end_of_the_run(tmp_path: Path) -> None:
    recording = _recording(tmp_path, "end")
    info = rows(recording, REPLAY.neighbor("front", 0, "info"), "TextDocument:text")
    assert info and all("matched: end of the run" in text[0] for _, text in info)
    assert not any("matched: frame" in text[0] for _, text in info)
    assert properties(recording)["failure_frames"] == "end"
