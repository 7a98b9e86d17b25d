"""Live camera codecs (`watch --camera-codec`): per-step logging cost, bytes, and how late video arrives.

Run: .venv/bin/python -m bench.bench_live_video [--real DIR]

Feeds the real ManiSkill-failgen episode (256 px, 69 frames, 3 views; `--real DIR`, else a simulated
256 px × 69-frame episode) frame by frame through `rfr_viz.panels.live_camera.LiveCameras` into a file, as
`watch` does, for jpeg / av1 / h264: the milliseconds a step's cameras take to log (median, worst;
the encoder's flush at the end counted apart), the file's bytes against JPEG, and the frames the
encoder holds back (a frame's sample reaches the viewer that many steps later).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import rerun as rr

from bench._timing import print_machine
from bench.bench_video import SHARED_EPISODE, simulated_episode
from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.camera_video import VideoEncoder
from rfr_viz.panels.live_camera import LiveCameras
from rfr_viz.panels.scores import set_frame_time
from robofailring import load_trajectory
from robofailring.data.model import Trajectory


def measure(trajectory: Trajectory, codec: CameraCodec, out: Path) -> tuple[float, float, float, int]:
    views = list(trajectory.views)
    length = min(len(frames) for frames in trajectory.views.values())
    fps = float(trajectory.fps or 10.0)
    images = {view: [frame.load() for frame in frames[:length]] for view, frames in trajectory.views.items()}
    rec = rr.RecordingStream("bench_live_video", recording_id=codec.value)
    rec.save(out)
    cameras = LiveCameras(rec, views, codec=codec, fps=fps)
    steps: list[float] = []
    for t in range(length):
        set_frame_time(rec, t, fps)
        started = time.perf_counter()
        for view in views:
            cameras.log(view, images[view][t], t)
        steps.append((time.perf_counter() - started) * 1000)
    started = time.perf_counter()
    cameras.finish()
    flush_ms = (time.perf_counter() - started) * 1000
    rec.flush()
    rec.disconnect()
    held = 0
    if codec is not CameraCodec.JPEG:  # frames given before the encoder gives out frame 0's sample
        encoder = VideoEncoder(codec, fps=fps)
        held = next((t for t in range(length) if encoder.encode(images[views[0]][t])), length)
        encoder.flush()
    return statistics.median(steps), max(steps), flush_ms, held


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, default=SHARED_EPISODE, help="the real ManiSkill episode folder")
    args = parser.parse_args()
    print_machine(libraries=("av",))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if args.real.is_dir():
            name, trajectory = "ManiSkill (real)", load_trajectory(args.real, task="FailPickCube-v1")
        else:
            print(f"{args.real} not found: a simulated 256 px episode instead")
            name = "sim"
            trajectory = load_trajectory(simulated_episode(work, size=256, frames=69), task="pick_cube")
        shape = next(iter(trajectory.views.values()))[0].load().shape
        length = min(len(frames) for frames in trajectory.views.values())
        print(f"{name}: {shape[1]}×{shape[0]} px × {length} frames × {len(trajectory.views)} views, fed live")
        print("| codec | recording | vs JPEG | step ms median / worst | flush ms | frames held back |")
        print("|---|---:|---:|---:|---:|---:|")
        jpeg_bytes = 0
        for codec in (CameraCodec.JPEG, CameraCodec.AV1, CameraCodec.H264):
            out = work / f"{codec.value}.rrd"
            median, worst, flush_ms, held = measure(trajectory, codec, out)
            size = out.stat().st_size
            jpeg_bytes = jpeg_bytes or size
            print(
                f"| {codec.value} | {size / 1e6:.2f} MB | {size / jpeg_bytes:.2f}× | "
                f"{median:.1f} / {worst:.1f} | {flush_ms:.0f} | {held} |"
            )


if __name__ == "__main__":
    main()
