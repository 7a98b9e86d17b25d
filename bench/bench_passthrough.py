"""Video sources logged as their own samples (no re-encoding): the time a recording's cameras take.

Run: .venv/bin/python -m bench.bench_passthrough [--real DIR] [--repeat 3]

The real ManiSkill-failgen episode (256 px, 69 frames, 3 views; `--real DIR`, else a simulated
256 px × 69-frame episode) is written as a video-episode folder (`<view>.mp4`) in AV1 (SVT-AV1,
the recordings' settings) and in H.264 without B-frames; `log_camera_views` then stores its cameras
with the same codec: as the file's own samples (the default for such a source) and, for comparison,
decoded and re-encoded (the frames handed over as a plain list, which hides the file). Per codec:
seconds (best of `--repeat`), recording bytes, and the PSNR of the first view's recorded samples
against the source PNGs.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from fractions import Fraction
from pathlib import Path

import av

from bench._timing import print_machine
from bench.bench_video import SHARED_EPISODE, camera_recording_bytes, psnr, simulated_episode
from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.camera_video import AV1_CRF, AV1_PRESET, EncodedVideo, decode_video, encode_video
from rfr_viz.panels.video_passthrough import passthrough
from robofailring import load_trajectory
from robofailring.data.model import Trajectory


def write_mp4(path: Path, frames: list, codec: CameraCodec, fps: int) -> None:
    with av.open(str(path), "w") as container:
        if codec is CameraCodec.AV1:
            stream = container.add_stream("libsvtav1", rate=fps)
            stream.options = {"g": "30", "crf": str(AV1_CRF), "preset": str(AV1_PRESET)}
        else:
            stream = container.add_stream("libx264", rate=fps)
            stream.options = {"g": "30", "crf": "23", "x264-params": "bframes=0"}
        stream.pix_fmt, stream.height, stream.width = "yuv420p", *frames[0].shape[:2]
        stream.time_base = Fraction(1, fps)
        for index, image in enumerate(frames):
            frame = av.VideoFrame.from_ndarray(image, format="rgb24")
            frame.pts = index
            container.mux(stream.encode(frame))
        container.mux(stream.encode())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, default=SHARED_EPISODE, help="the real ManiSkill episode folder")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print_machine(libraries=("av",))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if args.real.is_dir():
            name, source = "ManiSkill (real)", load_trajectory(args.real, task="FailPickCube-v1")
        else:
            name = "sim"
            source = load_trajectory(simulated_episode(work, size=256, frames=69), task="pick_cube")
        pixels = {view: [frame.load() for frame in frames] for view, frames in source.views.items()}
        length = min(len(frames) for frames in pixels.values())
        print(f"{name}: {len(pixels)} views × {length} frames, cameras only")
        print("| codec | stored as | seconds | recording | PSNR dB, first view (worst frame) |")
        print("|---|---|---:|---:|---:|")
        for codec in (CameraCodec.AV1, CameraCodec.H264):
            folder = work / f"{codec.value}_episode"
            folder.mkdir()
            for view, frames in pixels.items():
                write_mp4(folder / f"{view}.mp4", frames[:length], codec, 10)
            videos = load_trajectory(folder, task="pick_cube")
            hidden: Trajectory = replace(videos, views={v: list(f) for v, f in videos.views.items()})
            for label, trajectory in (("its own samples", videos), ("re-encoded", hidden)):
                seconds = []
                for attempt in range(args.repeat):
                    started = time.perf_counter()
                    size = camera_recording_bytes(trajectory, codec, work / f"{codec.value}{attempt}.rrd")
                    seconds.append(time.perf_counter() - started)
                view = next(iter(videos.views))
                kept = passthrough(trajectory.views[view], length, codec)
                if kept is None:
                    kept = encode_video((f.load() for f in trajectory.views[view]), codec, fps=10.0)
                mean, worst = psnr(
                    decode_video(EncodedVideo(codec, kept.samples, kept.keyframes, 0, 0)), pixels[view]
                )
                print(
                    f"| {codec.value} | {label} | {min(seconds):.2f} | {size / 1e6:.2f} MB | {mean:.1f} ({worst:.1f}) |"
                )


if __name__ == "__main__":
    main()
