"""`rfr_viz.show` without a Jupyter frontend: what it sends rerun-notebook's viewer, read back as a recording.

With no frontend the widget never says it is ready, so what `show` sent waits in the widget's queue
(`rerun_notebook.Viewer._event_queue`): the test reads it there, writes it to a file and opens that
with RrdReader, blueprint store and all.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from environment import require_module
from rrd import blueprint_names, properties, reader
from synthetic import write_episode

import rfr_viz
from rfr_viz.panels.umap import MemoryMap, memory_map
from rfr_viz.paths import APPLICATION_ID
from rfr_viz.recordings.notebook import InlineRecording, show
from rfr_viz.recordings.replay import record_replay
from robofailring import (
    CachedEncoder,
    DetectionTrace,
    FailureDetector,
    FailureMemory,
    Trajectory,
    load_encoder,
    load_trajectory,
)
from robofailring.errors import DataError, SettingError

require_module("rerun_notebook", "pip install -e '.[notebook]'")


@pytest.fixture(scope="module")
def replayed(
    pixels_memory_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Trajectory, DetectionTrace, MemoryMap]:
    tmp = tmp_path_factory.mktemp("notebook")
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp / "cache")
    memory = FailureMemory.load(pixels_memory_dir)
    trajectory = load_trajectory(
        write_episode(tmp / "pick_cube_grasp_wp2_episode9", "pick_cube", "grasp_wp2", length=8)
    )
    first = FailureDetector(memory, encoder, k=2).run(trajectory)
    trace = first.with_delta(float(np.median(first.max_similarity())))  # fires part-way through
    return trajectory, trace, memory_map(memory, directory=pixels_memory_dir)


@pytest.fixture(scope="module")
def recording(
    replayed: tuple[Trajectory, DetectionTrace, MemoryMap], tmp_path_factory: pytest.TempPathFactory
) -> Path:
    trajectory, trace, mapped = replayed
    return record_replay(
        trajectory, trace, out=tmp_path_factory.mktemp("rrd") / "replay.rrd", memory_map=mapped
    )


def _sent(shown: InlineRecording, tmp_path: Path) -> Path:
    """What the viewer widget was sent, as one file: each message is one `.rrd` (the widget's `send_rrd`)."""
    queue = shown.viewer._viewer._event_queue
    assert [content for content, _ in queue] == [{"type": "rrd"}]
    (buffers,) = [buffers for _, buffers in queue]
    assert buffers is not None and len(buffers) == 1
    sent = tmp_path / "sent.rrd"
    sent.write_bytes(buffers[0])
    return sent


def test_show_is_exported_lazily() -> None:
    assert {"show", "InlineRecording"} <= set(rfr_viz.__all__)
    assert rfr_viz.show is show and rfr_viz.InlineRecording is InlineRecording


def test_a_file_is_sent_whole_with_its_blueprint(recording: Path, tmp_path: Path) -> None:
    shown = show(recording, width=800, height=450, display=False)
    assert (shown.path, shown.recording_bytes) == (recording, recording.stat().st_size)
    sent = _sent(shown, tmp_path)
    assert sent.read_bytes() == recording.read_bytes()
    read = reader(sent)
    assert [(e.kind, e.application_id) for e in read.blueprints()] == [("blueprint", APPLICATION_ID)]
    names = blueprint_names(sent)
    assert names == blueprint_names(recording)
    assert {"front", "overhead", "wrist", "nearest memory entries"} <= set(names)
    assert any(name.startswith("δ = ") for name in names)  # the score plot, titled with its threshold
    assert (shown.viewer._viewer._width, shown.viewer._viewer._height) == (800, 450)
    assert show(str(recording), display=False).path == recording  # a path as a string too


def test_a_trace_is_recorded_by_record_replay_and_shown_the_same_way(
    replayed: tuple[Trajectory, DetectionTrace, MemoryMap], recording: Path, tmp_path: Path
) -> None:
    trajectory, trace, mapped = replayed
    shown = show(trace, trajectory=trajectory, memory_map=mapped, display=False)
    assert shown.path is None  # a temporary file, removed once sent
    sent = _sent(shown, tmp_path)
    assert shown.recording_bytes == sent.stat().st_size
    assert blueprint_names(sent) == blueprint_names(recording)  # the replay verb's own layout
    said = properties(sent)
    assert (said["task"], said["episode"], said["L"]) == ("pick_cube", trajectory.episode, trajectory.length)
    assert trace.t_det is not None and said["t_det"] == trace.t_det
    assert (shown.viewer._viewer._width, shown.viewer._viewer._height) == ("auto", "auto")


def test_a_trace_shown_with_out_keeps_its_recording(
    replayed: tuple[Trajectory, DetectionTrace, MemoryMap], tmp_path: Path
) -> None:
    trajectory, trace, mapped = replayed
    kept = tmp_path / "kept.rrd"
    shown = show(trace, trajectory=trajectory, memory_map=mapped, focus_frame=3, out=kept, display=False)
    assert shown.path == kept and kept.stat().st_size == shown.recording_bytes
    assert properties(kept)["focus_frame"] == 3
    assert _sent(shown, tmp_path).read_bytes() == kept.read_bytes()


def test_wrong_inputs_are_the_projects_errors(
    replayed: tuple[Trajectory, DetectionTrace, MemoryMap], recording: Path, tmp_path: Path
) -> None:
    trajectory, trace, _ = replayed
    with pytest.raises(SettingError, match="needs the trajectory"):
        show(trace, display=False)
    other = load_trajectory(write_episode(tmp_path / "push_cube_slip_wp3_episode1", "push_cube", "slip_wp3"))
    with pytest.raises(SettingError, match="the trace is of pick_cube/"):
        show(trace, trajectory=other, display=False)
    with pytest.raises(SettingError, match="for a trace, not a recording"):
        show(recording, trajectory=trajectory, display=False)
    with pytest.raises(DataError, match="no recording at"):
        show(tmp_path / "missing.rrd", display=False)
    (tmp_path / "notes.rrd").write_text("not a recording")
    with pytest.raises(DataError, match="is not a Rerun recording"):
        show(tmp_path / "notes.rrd", display=False)


def test_without_rerun_notebook_show_names_the_notebook_extra() -> None:
    probe = (
        "import sys; sys.modules['rerun_notebook'] = None\n"
        "import rfr_viz\n"
        "try:\n    rfr_viz.show\nexcept ImportError as error:\n    print(type(error).__name__, error.extra, error)\n"
    )
    printed = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=120
    )
    assert printed.stdout.startswith("MissingExtraError notebook rerun-notebook is not installed"), printed
    assert 'pip install "robofailring[notebook]"' in printed.stdout
