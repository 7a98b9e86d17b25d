"""Watching live: `watch --save` equals `detect --json`, the step sink, and a stream into a real viewer."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from environment import require_viewer
from ports import free_port
from rrd import batches, entity_paths, has_footer, properties, psnr, rows
from synthetic import VIEWS, synthetic_frame, write_episode
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from rfr_viz.codecs import CameraCodec
from rfr_viz.jobs.explain import read_report
from rfr_viz.panels.camera_video import KEYFRAME_INTERVAL, EncodedVideo, decode_video, encode_video
from rfr_viz.panels.live_camera import LiveCameras, live_codec
from rfr_viz.panels.scores import set_frame_time
from rfr_viz.paths import REPLAY, camera
from rfr_viz.recordings.live import LiveRecording
from rfr_viz.recordings.live_target import LiveTarget
from rfr_viz.viewer.control import WINDOW, _viewer_process
from robofailring import (
    DetectorSession,
    FailureDetector,
    FailureMemory,
    Frame,
    StepResult,
    load_encoder,
    load_trajectory,
)
from robofailring.data.images import write_png
from robofailring.errors import OutputError

runner = CliRunner()
DELTA = "0.97"  # the synthetic episode's S_t crosses it part-way through (frame 6 of 8)


@pytest.fixture(scope="module")
def episode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("episodes") / "pick_cube_grasp_wp2_episode9"
    return write_episode(folder, "pick_cube", "grasp_wp2", length=8, shift=1)


def _detect_json(episode: Path, pixels_memory_dir: Path) -> dict:
    result = runner.invoke(
        app,
        ["detect", str(episode), "--memory", str(pixels_memory_dir), "--delta", DELTA, "--k", "3", "--json"],
    )
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def _watch(episode: Path, pixels_memory_dir: Path, *target: str) -> str:
    result = runner.invoke(
        app,
        [
            "watch",
            str(episode),
            "--memory",
            str(pixels_memory_dir),
            "--delta",
            DELTA,
            "--k",
            "3",
            "--speed",
            "0",
            *target,
        ],
    )
    assert result.exit_code == 0, result.output
    return result.stdout


def test_watch_save_equals_detect_json(episode: Path, pixels_memory_dir: Path, tmp_path: Path) -> None:
    detected = _detect_json(episode, pixels_memory_dir)
    assert detected["t_det"] is not None and 0 < detected["t_det"] < detected["length"]
    saved = tmp_path / "live.rrd"
    out = _watch(episode, pixels_memory_dir, "--save", str(saved))
    assert f"FAILURE at frame {detected['t_det']} in view {detected['detected_view']}" in out
    for view, scored in detected["views"].items():
        found = rows(saved, REPLAY.score(view, "paper"), "Scalars:scalars")
        assert [frame for frame, _ in found] == list(range(detected["length"]))
        np.testing.assert_allclose([value[0] for _, value in found], scored["similarity"], atol=1e-6)
        assert [frame for frame, _ in rows(saved, camera(view), "EncodedImage:blob")] == list(
            range(detected["length"])
        )
    assert properties(saved, "camera")["codec"] == "jpeg"  # the default: a JPEG per live frame
    state = rows(saved, REPLAY.state, "Scalars:scalars")
    assert next(frame for frame, value in state if value[0] == 1.0) == detected["t_det"]
    found = properties(saved)
    assert found["t_det"] == detected["t_det"] and found["detected_view"] == detected["detected_view"]
    assert found["L"] == detected["length"] and found["delta"] == float(DELTA)
    events = rows(saved, REPLAY.event, "TextLog:text")
    assert [frame for frame, _ in events] == [detected["t_det"]]
    # `explain` works on a live recording too (the folders its images may come from: named when explained)
    assert read_report(saved).to_dict() == detected["report"] | {"roots": []}

    replayed = runner.invoke(
        app,
        [
            "replay",
            str(episode),
            "--memory",
            str(pixels_memory_dir),
            "--delta",
            DELTA,
            "--k",
            "3",
            "--out",
            str(tmp_path / "replay"),
        ],
    )
    assert replayed.exit_code == 0, replayed.output
    (replay,) = (tmp_path / "replay").glob("*.rrd")
    assert entity_paths(saved) == entity_paths(replay)  # the same entity paths as a replay


def test_watch_says_a_camera_gone_dark_and_ends_with_status_3(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    """Issue 50: frames blank to the encoder are not a run without failure: `watch` names the view and its
    frames, never says "no failure detected", and ends with the "some inputs skipped" status (3)."""
    folder = Path(shutil.copytree(episode, tmp_path / episode.name))
    for t in range(3, 8):
        write_png(folder / "front" / f"{t}.png", np.zeros((32, 32, 3), np.uint8))
        write_png(folder / "overhead" / f"{t}.png", np.full((32, 32, 3), 255, np.uint8))
    for t in range(8):
        write_png(folder / "wrist" / f"{t}.png", np.zeros((32, 32, 3), np.uint8))
    args = ["watch", str(folder), "--memory", str(pixels_memory_dir), "--delta", "1", "--speed", "0"]
    result = runner.invoke(app, [*args, "--save", str(tmp_path / "live.rrd")])
    assert result.exit_code == 3, result.output
    assert "view front: 5 of 8 scored frame(s) (3–7) are blank to the encoder" in result.stderr
    assert "view overhead: 5 of 8 scored frame(s) (3–7) are blank to the encoder" in result.stderr
    assert "view wrist: its first frame is blank to the encoder" in result.stderr
    assert "no failure detected" not in result.stdout
    assert "8 steps watched: no alarm, but 3 view(s) blind for some frames" in result.stdout
    assert "BlindCameraWarning" not in result.output  # said once, in the summary


@pytest.mark.parametrize("codec", ["av1", "h264"])
def test_watch_encodes_video_frame_by_frame(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path, codec: str
) -> None:
    folder = tmp_path / episode.name  # the episode at 96 px, so that video has real pixels to compress
    for v, view in enumerate(VIEWS):
        (folder / view).mkdir(parents=True)
        for t in range(8):
            write_png(
                folder / view / f"{t}.png", synthetic_frame("pick_cube", "grasp_wp2", v, t + 1, 9, size=96)
            )
    saved = tmp_path / f"live-{codec}.rrd"
    _watch(folder, pixels_memory_dir, "--save", str(saved), "--camera-codec", codec)
    trajectory = load_trajectory(folder)
    length = properties(saved)["L"]
    assert length == 8
    camera_properties = properties(saved, "camera")
    assert camera_properties["codec"] == codec and camera_properties["keyframe_interval"] == KEYFRAME_INTERVAL
    for view in trajectory.views:
        assert f"{view}: {codec}" in camera_properties["views"]
        samples = rows(saved, camera(view), "VideoStream:sample")
        assert [frame for frame, _ in samples] == list(range(length))  # one sample per frame, at its frame
        assert not rows(saved, camera(view), "EncodedImage:blob")
        keyframes = [bool(key[0]) for _, key in rows(saved, camera(view), "VideoStream:is_keyframe")]
        assert keyframes[0] and len(keyframes) == length
        (codec_row,) = [
            batch.column("VideoStream:codec").to_pylist()
            for batch in batches(saved, camera(view))
            if "VideoStream:codec" in batch.schema.names
        ]
        assert codec_row == [[{"av1": 0x61763031, "h264": 0x61766331}[codec]]]
        video = EncodedVideo(CameraCodec(codec), [bytes(s[0]) for _, s in samples], keyframes, 96, 96)
        decoded = decode_video(video)
        source = [frame.load() for frame in trajectory.views[view][:length]]
        assert len(decoded) == length
        # pixel-close to the source, as a replay's video (tests/test_camera_video.py)
        assert min(psnr(d, s) for d, s in zip(decoded, source, strict=True)) > 30.0


def test_live_auto_means_jpeg_and_images_stay_images(tmp_path: Path) -> None:
    assert live_codec("auto") is CameraCodec.JPEG and live_codec("av1") is CameraCodec.AV1
    saved = tmp_path / "frames.rrd"
    rec = rr.RecordingStream("test", recording_id="frames")
    rec.save(saved)
    cameras = LiveCameras(rec, ["front"], codec="av1", fps=10.0)
    frames = [synthetic_frame("pick_cube", "grasp_wp2", 0, t, 12, size=96) for t in range(12)]
    for t, frame in enumerate(frames):
        set_frame_time(rec, t, 10.0)
        cameras.log("front", frame, t)
    cameras.finish()
    rec.flush()
    rec.disconnect()
    samples = rows(saved, camera("front"), "VideoStream:sample")
    assert [frame for frame, _ in samples] == list(range(12))
    keyframes = [bool(key[0]) for _, key in rows(saved, camera("front"), "VideoStream:is_keyframe")]
    video = EncodedVideo(CameraCodec.AV1, [bytes(s[0]) for _, s in samples], keyframes, 96, 96)
    whole = encode_video(frames, CameraCodec.AV1, fps=10.0)  # what a replay stores for the same frames
    assert video.samples == whole.samples and video.keyframes == whole.keyframes
    decoded = decode_video(video)
    assert min(psnr(d, s) for d, s in zip(decoded, frames, strict=True)) > 30.0


class Collect:
    """A user's own sink: keeps what each step handed it."""

    def __init__(self) -> None:
        self.seen: list[tuple[int, list[str], bool]] = []

    def on_step(
        self, session: DetectorSession, frames: Mapping[str, np.ndarray | Frame], result: StepResult
    ) -> None:
        assert session.t == result.t  # called before the session moves on
        self.seen.append((result.t, sorted(frames), result.state))


def test_a_robot_loop_with_its_own_sink_and_the_rerun_sink(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    memory = FailureMemory.load(pixels_memory_dir)
    detector = FailureDetector(memory, load_encoder("pixels"), delta=float(DELTA), k=3)
    trajectory = load_trajectory(episode)
    frames = [{view: trajectory.views[view][t].load() for view in trajectory.views} for t in range(8)]

    collected = Collect()
    plain = detector.session("pick_cube", sink=collected)
    states = [plain.step(images).state for images in frames]
    assert collected.seen == [(t, ["front", "overhead", "wrist"], states[t]) for t in range(8)]

    saved = tmp_path / "robot.rrd"
    target = LiveTarget(save=saved)
    with LiveRecording.open(detector, "pick_cube", views=list(trajectory.views), target=target) as live:
        session = detector.session("pick_cube", sink=live)
        similarity = [session.step(images).similarity["wrist"] for images in frames]  # live RGB arrays
    assert live.fired_at == plain.fired_at == states.index(True)
    found = rows(saved, REPLAY.score("wrist", "paper"), "Scalars:scalars")
    np.testing.assert_allclose([value[0] for _, value in found], similarity, atol=1e-6)
    assert len(rows(saved, camera("front"), "EncodedImage:blob")) == 8
    assert live.report is not None and live.report.current_image is None  # an array has no file to show a VLM
    # no footer: its manifest of every chunk would stay in memory for the whole session (bench/bench_soak.py)
    assert not has_footer(saved)


def test_a_failed_block_leaves_no_file(pixels_memory_dir: Path, tmp_path: Path) -> None:
    detector = FailureDetector(FailureMemory.load(pixels_memory_dir), load_encoder("pixels"))
    saved = tmp_path / "broken.rrd"
    opened = LiveRecording.open(detector, "pick_cube", views=["front"], target=LiveTarget(save=saved))
    with pytest.raises(RuntimeError, match="robot fell over"), opened:
        raise RuntimeError("robot fell over")
    assert not saved.exists() and not list(tmp_path.iterdir())
    with pytest.raises(ValueError, match="needs somewhere to go"):
        LiveTarget()


@pytest.mark.viewer
def test_watch_connect_streams_into_a_running_viewer(episode: Path, pixels_memory_dir: Path) -> None:
    require_viewer()
    from rerun.experimental import ViewerClient

    deadline = time.monotonic() + 90
    with _viewer_process(WINDOW, deadline) as port:
        url = f"rerun+http://127.0.0.1:{port}/proxy"
        _watch(episode, pixels_memory_dir, "--connect", url)
        client = ViewerClient.connect(url)
        while True:
            state = client.get_state()
            shown = [
                r for r in state.recordings if any(t.name == "frame" and t.end == 7 for t in r.timelines)
            ]
            if shown and not state.loading:
                break
            assert time.monotonic() < deadline, f"the viewer never showed the stream: {state}"
            time.sleep(0.2)
        (recording,) = shown
        schema = client.get_recording_schema(recording.store_id, paths_only=True)
        paths = {entity.entity_path for entity in schema.entities}
        expected = {camera(view) for view in ("front", "overhead", "wrist")}
        expected |= {
            REPLAY.score("front", "paper"),
            REPLAY.threshold("paper"),
            REPLAY.state,
            REPLAY.event,
            REPLAY.report,
        }
        assert expected <= paths, sorted(paths)
        frame = next(t for t in recording.timelines if t.name == "frame")
        assert (frame.start, frame.end) == (0, 7)


def test_watch_without_a_viewer_is_a_clear_error(episode: Path, pixels_memory_dir: Path) -> None:
    port = free_port()  # nobody listens on it
    result = runner.invoke(
        app,
        [
            "watch",
            str(episode),
            "--memory",
            str(pixels_memory_dir),
            "--connect",
            f"rerun+http://127.0.0.1:{port}/proxy",
        ],
    )
    # exit 1: the environment (no viewer there), not the command line, is what is wrong
    assert (
        result.exit_code == 1 and "no Rerun viewer listens at" in result.stderr and "--spawn" in result.stderr
    )


def test_watch_save_refuses_any_file_that_is_not_a_recording(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    """`watch --save` never writes over a memory's manifest, a labels file, a frame of the episode it
    watches (issue 35, item 2) or a recording of another application: one error line, before any work,
    each file as it was."""
    labels = tmp_path / "labels.csv"
    labels.write_text("episode,outcome\npick_cube_grasp_wp2_episode9,failure\n")
    frame = next(path for path in sorted(episode.rglob("*.png")))
    theirs = tmp_path / "lab.rrd"  # a Rerun recording of the user's own tools (issue 50, data loss)
    with rr.RecordingStream("my_robot_lab", recording_id="lab-session") as rec:
        rec.save(theirs)
        rec.log("arm/torque", rr.Scalars(1.5))
    targets = {
        pixels_memory_dir / "manifest.json": "lies inside the input",
        labels: "is not a Rerun recording",
        frame: "lies inside the input",
        tmp_path: "is not a Rerun recording",  # a folder
        theirs: "is not a Rerun recording written by robofailring",
    }
    for target, why in targets.items():
        before = target.read_bytes() if target.is_file() else sorted(p.name for p in target.iterdir())
        result = runner.invoke(
            app,
            [
                "watch",
                str(episode),
                "--memory",
                str(pixels_memory_dir),
                "--speed",
                "0",
                "--save",
                str(target),
            ],
        )
        errors = [line for line in result.output.splitlines() if line.startswith("error:")]
        assert result.exit_code == 2 and len(errors) == 1 and why in errors[0], result.output
        after = target.read_bytes() if target.is_file() else sorted(p.name for p in target.iterdir())
        assert after == before
    detector = FailureDetector(FailureMemory.load(pixels_memory_dir), load_encoder("pixels"))
    live = LiveRecording.open(detector, "pick_cube", views=list(VIEWS), target=LiveTarget(save=labels))
    with (
        pytest.raises(OutputError, match="is not a Rerun recording"),
        live,
    ):  # the library's live recording too
        pass
    assert labels.read_text().startswith("episode,outcome")


STOP_AT_STEP_3 = """
import os, signal, sys
from rfr_viz.recordings.live import LiveRecording
stop = getattr(signal, sys.argv[1])
real = LiveRecording.on_step
def on_step(self, session, frames, result):
    real(self, session, frames, result)
    if result.t == 3:  # a person (or a scheduler) stops the robot's watch part-way
        os.kill(os.getpid(), stop)
LiveRecording.on_step = on_step
sys.argv[1:] = sys.argv[3:]
from rfr_viz.cli.app import main
sys.exit(main())
"""


@pytest.mark.parametrize(
    ("stop", "code", "said"),
    [("SIGINT", 130, "interrupted (Ctrl-C)"), ("SIGTERM", 143, "terminated (SIGTERM)")],
)
def test_a_stopped_watch_keeps_what_it_recorded_as_a_whole_file(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path, stop: str, code: int, said: str
) -> None:
    """Issue 45 item 6: Ctrl-C threw the live stream away and SIGTERM left its temporary file; now the
    steps recorded are saved as a complete recording, and the command says so."""
    saved = tmp_path / "live.rrd"
    command = [sys.executable, "-c", STOP_AT_STEP_3, stop, "-", "watch", str(episode), "--memory",
               str(pixels_memory_dir), "--speed", "0", "--save", str(saved)]  # fmt: skip
    result = subprocess.run(
        command, capture_output=True, text=True, check=False, env={**os.environ, "ROBOFAILRING_PROGRESS": "0"}
    )
    assert result.returncode == code, result.stderr
    assert f"error: {said}" in result.stderr and "stopped after 4 step(s)" in result.stderr
    assert [frame for frame, _ in rows(saved, REPLAY.state, "Scalars:scalars")] == [0, 1, 2, 3]
    assert properties(saved)["L"] == 4  # its properties were written: a whole recording
    assert sorted(p.name for p in tmp_path.iterdir()) == ["live.rrd"]  # no temporary file left


HOLD_AT_STEP_3 = """
import sys, time
from pathlib import Path
from rfr_viz.recordings.live import LiveRecording
ready, go = Path(sys.argv[1]), Path(sys.argv[2])
real = LiveRecording.on_step
def on_step(self, session, frames, result):
    real(self, session, frames, result)
    if result.t == 3:  # the robot is still being watched while another job runs
        ready.touch()
        for _ in range(6000):  # at most 10 minutes: a test that never says go fails, it does not hang
            if go.exists():
                break
            time.sleep(0.1)
LiveRecording.on_step = on_step
sys.argv[1:] = sys.argv[4:]
from rfr_viz.cli.app import main
sys.exit(main())
"""


def _watch_held_at_step_3(episode: Path, memory: Path, save: Path, signals: Path) -> subprocess.Popen[str]:
    """`watch --save` in its own process, held at its fourth step until `signals/go` appears."""
    command = [sys.executable, "-c", HOLD_AT_STEP_3, str(signals / "ready"), str(signals / "go"), "-", "watch",
               str(episode), "--memory", str(memory), "--speed", "0", "--save", str(save)]  # fmt: skip
    watcher = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "ROBOFAILRING_PROGRESS": "0"},
    )  # fmt: skip
    while not (signals / "ready").exists():
        assert watcher.poll() is None, watcher.communicate()
        time.sleep(0.05)
    return watcher


def test_a_replay_into_the_folder_of_a_running_watch_keeps_its_recording(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    """Issue 50, data loss: a replay into `rec/` deleted the temporary file of a running
    `watch --save rec/mylive.rrd` as a leftover, and the whole live recording was lost. The watch's
    temporary file is held (flock) while it writes, so the replay's cleaning leaves it alone."""
    rec = tmp_path / "rec"
    save = rec / "mylive.rrd"
    watcher = _watch_held_at_step_3(episode, pixels_memory_dir, save, tmp_path)
    try:
        held = [p.name for p in rec.iterdir() if p.name.startswith(".mylive.rrd.rfr-")]
        assert len(held) == 1  # the watch is writing its temporary file now
        replayed = runner.invoke(
            app,
            ["replay", str(episode), "--memory", str(pixels_memory_dir), "--out", str(rec), "--delta", DELTA],
        )
        assert replayed.exit_code == 0, replayed.output
        assert (rec / held[0]).exists()  # not taken for a leftover of a killed write
    finally:
        (tmp_path / "go").touch()
        _, stderr = watcher.communicate(timeout=300)
    assert watcher.returncode == 0, stderr
    assert [frame for frame, _ in rows(save, REPLAY.state, "Scalars:scalars")] == list(range(8))
    assert properties(save)["L"] == 8
    assert sorted(p.name for p in rec.iterdir() if p.suffix == ".rrd") == [
        "mylive.rrd",
        f"pick_cube__{episode.name}.rrd",
    ]
    assert not [p.name for p in rec.iterdir() if p.name.startswith(".")]  # nothing left behind


def test_a_second_watch_saving_to_the_same_file_stops_before_any_work(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    """`watch --save` holds its file's output lock: a second one into the same file is refused at once
    (status 1, the file named) and the first one's recording is whole."""
    save = tmp_path / "mylive.rrd"
    watcher = _watch_held_at_step_3(episode, pixels_memory_dir, save, tmp_path)
    try:
        second = runner.invoke(
            app,
            ["watch", str(episode), "--memory", str(pixels_memory_dir), "--speed", "0", "--save", str(save)],
        )
    finally:
        (tmp_path / "go").touch()
        _, stderr = watcher.communicate(timeout=300)
    errors = [line for line in second.output.splitlines() if line.startswith("error:")]
    assert second.exit_code == 1 and len(errors) == 1 and str(save) in errors[0], second.output
    assert "another robofailring process is writing" in errors[0]
    assert watcher.returncode == 0, stderr
    assert properties(save)["L"] == 8


def _error_lines(output: str) -> list[str]:
    return [line for line in output.splitlines() if line.startswith("error:")]


def test_an_evaluate_into_the_file_of_a_running_watch_stops_before_work(
    aha_dataset: Path, episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    """Outside use round 6, N3, data loss: `evaluate --out rec --name mylive` wrote rec/mylive.rrd while
    a `watch --save rec/mylive.rrd` ran, and the watch then renamed its stream over it. The evaluation
    holds each of its files' lock before work: it stops (status 1, the file named), nothing written."""
    rec = tmp_path / "rec"
    save = rec / "mylive.rrd"
    watcher = _watch_held_at_step_3(episode, pixels_memory_dir, save, tmp_path)
    try:
        evaluated = runner.invoke(
            app, ["evaluate", str(aha_dataset), "--encoder", "pixels", "--out", str(rec), "--name", "mylive"]
        )
    finally:
        (tmp_path / "go").touch()
        _, stderr = watcher.communicate(timeout=300)
    errors = _error_lines(evaluated.output)
    assert evaluated.exit_code == 1 and len(errors) == 1, evaluated.output
    assert str(save) in errors[0] and "another robofailring process is writing" in errors[0]
    assert watcher.returncode == 0, stderr
    assert properties(save)["L"] == 8  # the watch's recording, whole
    assert sorted(p.name for p in rec.iterdir()) == ["mylive.rrd"]  # no table of a run that never ran


def test_a_replay_onto_the_file_of_a_running_watch_stops_before_work(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    """Outside use round 6, N4: a replay wrote the very file a running `watch --save` was writing, and
    the watch's rename replaced it, with no word from either. The replay now checks each recording's
    lock before work and stops (status 1, the file named); the watch's recording is whole."""
    rec = tmp_path / "rec"
    save = rec / f"pick_cube__{episode.name}.rrd"
    watcher = _watch_held_at_step_3(episode, pixels_memory_dir, save, tmp_path)
    try:
        replayed = runner.invoke(
            app,
            ["replay", str(episode), "--memory", str(pixels_memory_dir), "--out", str(rec), "--delta", DELTA],
        )
    finally:
        (tmp_path / "go").touch()
        _, stderr = watcher.communicate(timeout=300)
    errors = _error_lines(replayed.output)
    assert replayed.exit_code == 1 and len(errors) == 1, replayed.output
    assert str(save) in errors[0] and "another robofailring process is writing" in errors[0]
    assert watcher.returncode == 0, stderr
    assert properties(save)["L"] == 8
    assert sorted(p.name for p in rec.iterdir()) == [save.name]


def test_a_watch_never_renames_over_a_file_another_process_wrote_meanwhile(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    """A writer that takes no lock (a copy, an older robofailring) puts a file where a running watch
    saves: the watch keeps that file and saves its own stream beside it, under a free name, and says so
    in one `error:` line (status 1): nothing replaced, nothing lost."""
    save = tmp_path / "rec" / "mylive.rrd"
    watcher = _watch_held_at_step_3(episode, pixels_memory_dir, save, tmp_path)
    try:
        save.write_bytes(b"written by someone else")
    finally:
        (tmp_path / "go").touch()
        _, stderr = watcher.communicate(timeout=300)
    kept = save.with_name("mylive-2.rrd")
    errors = _error_lines(stderr)
    assert watcher.returncode == 1 and len(errors) == 1, stderr
    assert str(save) in errors[0] and str(kept) in errors[0]
    assert save.read_bytes() == b"written by someone else"
    assert properties(kept)["L"] == 8  # the watch's stream, whole, under the free name
    assert sorted(p.name for p in save.parent.iterdir()) == ["mylive-2.rrd", "mylive.rrd"]
