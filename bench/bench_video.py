"""Camera codecs in recordings (issue 17): bytes, encode speed, PSNR and time to show any frame.

Run: .venv/bin/python -m bench.bench_video [--real DIR] [--frames 150] [--size 480]

Episodes: the real ManiSkill-failgen episode (`--real DIR`; default: `shared/data/maniskill-failgen-episode` beside the checkout,
256 px, 69 frames, 3 views; skipped with a message when absent), and episodes of the project's
simulator (`robofailring.sim`): 480 px × ≥ 150 frames for the target; 128 px × 40 (the demo's) and
256 px × 32 (≈ 2 Mpx per view, `auto`'s threshold) for the threshold.
Per episode and codec: the bytes of a recording holding only `/camera/<view>` (what the codec
changes) against the JPEG one, encode frames/s, PSNR of the decoded frames against the source
pixels, and the time to show an arbitrary frame (decode from its last keyframe; median and worst).
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np
import rerun.blueprint as rrb

from bench._timing import print_machine
from rfr_viz.codecs import CameraCodec
from rfr_viz.panels.camera_video import KEYFRAME_INTERVAL, EncodedVideo, decode_video, encode_video
from rfr_viz.panels.cameras import log_camera_views
from rfr_viz.panels.scores import time_columns
from rfr_viz.recordings.replay import open_recording
from robofailring import load_trajectory
from robofailring.data.images import decode_image, encode_jpeg, write_png
from robofailring.data.model import Trajectory

SHARED_EPISODE = Path(__file__).resolve().parents[2] / "shared" / "data" / "maniskill-failgen-episode"
CODECS = (CameraCodec.JPEG, CameraCodec.AV1, CameraCodec.H264)


def simulated_episode(root: Path, *, size: int, frames: int) -> Path:
    """One simulated pick_cube grasp failure written as an episode folder of PNG views."""
    from robofailring.sim import run_episode

    folder = root / f"sim_{size}px_{frames}f"
    with run_episode("pick_cube", "grasp", seed=3, image_size=size, frames=frames) as run:
        for t, images in enumerate(run):
            for view, image in images.items():
                (folder / view).mkdir(parents=True, exist_ok=True)
                write_png(folder / view / f"{t}.png", image)
    return folder


def camera_recording_bytes(trajectory: Trajectory, codec: CameraCodec, out: Path) -> int:
    views = list(trajectory.views)
    length = min(len(frames) for frames in trajectory.views.values())
    with open_recording(out, rrb.Blueprint(rrb.Spatial2DView(origin="/camera")), recording_id=None) as rec:
        log_camera_views(
            rec, trajectory, views=views, length=length, indexes=lambda f: time_columns(f, 10.0), codec=codec
        )
    return out.stat().st_size


def psnr(decoded: Sequence[np.ndarray], source: Sequence[np.ndarray]) -> tuple[float, float]:
    """Overall PSNR (dB, from the mean squared error of all frames) and the worst frame's."""
    errors = [
        float(np.mean((d[: s.shape[0], : s.shape[1]].astype(np.float64) - s) ** 2))
        for d, s in zip(decoded, source, strict=True)
    ]

    def db(mse: float) -> float:
        return math.inf if mse == 0 else 10 * math.log10(255.0**2 / mse)

    return db(statistics.fmean(errors)), db(max(errors))


def seek_ms(show: Callable[[int], object], count: int) -> tuple[float, float]:
    """Median and worst time to show each frame of `count` (decoding from scratch every time)."""
    times = []
    for target in range(count):
        start = time.perf_counter()
        show(target)
        times.append((time.perf_counter() - start) * 1000)
    return statistics.median(times), max(times)


def video_seek(video: EncodedVideo) -> Callable[[int], object]:
    keyframes = [i for i, key in enumerate(video.keyframes) if key]

    def show(target: int) -> object:
        start = max(k for k in keyframes if k <= target)
        part = EncodedVideo(
            video.codec, video.samples[start:], video.keyframes[start:], video.width, video.height
        )
        return decode_video(part, upto=target - start)[-1]

    return show


def measure(name: str, trajectory: Trajectory, work: Path) -> list[str]:
    views = {view: [frame.load() for frame in frames] for view, frames in trajectory.views.items()}
    length = min(len(frames) for frames in views.values())
    height, width = next(iter(views.values()))[0].shape[:2]
    total = length * len(views)
    rows = []
    jpeg_recording = 0
    for codec in CODECS:
        size = camera_recording_bytes(trajectory, codec, work / f"{name}-{codec.value}.rrd")
        jpeg_recording = jpeg_recording or size
        start = time.perf_counter()
        if codec is CameraCodec.JPEG:
            blobs = {
                view: [encode_jpeg(image) for image in images[:length]] for view, images in views.items()
            }
            encode_s = time.perf_counter() - start
            decoded = [decode_image(b, source="jpeg") for view in views for b in blobs[view]]
            first = blobs[next(iter(views))]
            seek = seek_ms(lambda t, first=first: decode_image(first[t], source="jpeg"), length)
        else:
            videos = {
                view: encode_video(images[:length], codec, fps=10.0, source=view)
                for view, images in views.items()
            }
            encode_s = time.perf_counter() - start
            decoded = [frame for video in videos.values() for frame in decode_video(video)]
            seek = seek_ms(video_seek(videos[next(iter(views))]), length)
        overall, worst = psnr(decoded, [image for view in views for image in views[view][:length]])
        rows.append(
            f"| {name} | {width}×{height}×{length}×{len(views)} | {codec.value} | {size / 1e6:.2f} MB | "
            f"{size / jpeg_recording:.2f}× | {total / encode_s:.0f} | {overall:.1f} (worst {worst:.1f}) | "
            f"{seek[0]:.1f} / {seek[1]:.1f} |"
        )
        print(rows[-1], flush=True)
    return rows


def keyframe_rows(trajectory: Trajectory) -> None:
    """AV1 bytes against worst-case seek for a few keyframe intervals (one view)."""
    view = next(iter(trajectory.views))
    images = [frame.load() for frame in trajectory.views[view]]
    print("\n| keyframe interval | AV1 bytes (one view) | show any frame: median / worst ms |")
    print("|---:|---:|---:|")
    for interval in (10, KEYFRAME_INTERVAL, 60, 150):
        video = encode_video(images, CameraCodec.AV1, fps=10.0, keyframe_interval=interval)
        median, worst = seek_ms(video_seek(video), len(images))
        print(f"| {interval} | {video.bytes / 1e3:.0f} kB | {median:.1f} / {worst:.1f} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, default=SHARED_EPISODE, help="the real ManiSkill episode folder")
    parser.add_argument("--size", type=int, default=480, help="simulated image size (px)")
    parser.add_argument("--frames", type=int, default=150, help="simulated frames (≥ 150 for the target)")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    print_machine(libraries=("av",))  # its wheel bundles the FFmpeg and SVT-AV1 the sizes depend on
    print(
        "| episode | W×H×frames×views | codec | camera recording | vs JPEG | encode frames/s | "
        "PSNR dB | show any frame: median / worst ms |"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory(prefix="rfr-bench-video-") as tmp:
        work = Path(tmp)
        if args.real.is_dir():
            measure("ManiSkill (real)", load_trajectory(args.real, task="FailPickCube-v1"), work)
        else:
            print(f"(skipped the real ManiSkill episode: {args.real} is not there)")
        for size, frames, name in ((128, 40, "sim (demo size)"), (256, 32, "sim (near auto's threshold)")):
            measure(
                name,
                load_trajectory(simulated_episode(work, size=size, frames=frames), task="pick_cube"),
                work,
            )
        big = load_trajectory(simulated_episode(work, size=args.size, frames=args.frames), task="pick_cube")
        measure("sim", big, work)
        keyframe_rows(big)


if __name__ == "__main__":
    main()
