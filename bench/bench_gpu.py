"""CUDA figures for the CLIP encoders (run where a GPU is present): per-frame detection latency of
ViT-B/32 and ViT-L/14 for 3 views (paper Table 3/4), and the project encoder against open_clip's
`encode_image` on the same batch. Random-initialised weights: speed does not depend on their values.

Then the ONNX path (`@onnx`, docs/runtime.md) on ONNX Runtime's CUDA execution provider, 3-view step and
batch of 64 against torch's, where the installed ONNX Runtime has that provider (onnxruntime-gpu; the
plain onnxruntime package has none, and this part then says so and is skipped). int8 is not timed on
the GPU: its dynamically quantized MatMuls run on ONNX Runtime's CPU kernels.

Run: python -m bench.bench_gpu
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

from bench._timing import median_ms, print_machine
from robofailring import FailureDetector, FailureMemory, load_encoder
from robofailring.memory.failure import MemoryEntry
from robofailring.memory.pairs import pair_vectors


def memory_for(identity: str, dim: int, entries: int = 15_000, tasks: int = 80) -> FailureMemory:
    rng = np.random.default_rng(0)
    vectors = pair_vectors(
        rng.standard_normal((entries, dim)), rng.standard_normal((entries, dim)), pairing="concat"
    )
    meta = [
        MemoryEntry(
            task=f"task_{i % tasks}", symbol="slip_wp3", episode=f"e{i}", view="front", start="", end=""
        )
        for i in range(entries)
    ]
    return FailureMemory(vectors, meta, encoder=identity)


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    print_machine(libraries=("torch",))
    import open_clip
    import torch
    from PIL import Image

    device = "cuda" if torch.cuda.is_available() else "cpu"
    print(
        f"device: {device} ({torch.cuda.get_device_name(0) if device == 'cuda' else 'CPU'}), torch {torch.__version__}"
    )
    rng = np.random.default_rng(1)
    views = {v: rng.integers(0, 255, (128, 128, 3), dtype=np.uint8) for v in ("front", "overhead", "wrist")}
    batch = [rng.integers(0, 255, (128, 128, 3), dtype=np.uint8) for _ in range(64)]
    workspace = tempfile.TemporaryDirectory()  # the checkpoints, kept for the ONNX export
    for model_name in ("ViT-B-32", "ViT-L-14"):
        torch.manual_seed(0)
        folder = Path(workspace.name)
        checkpoint = folder / f"{model_name}.pt"
        torch.save(open_clip.create_model(model_name, pretrained=None).state_dict(), checkpoint)
        checkpoint_spec = f"open_clip:{model_name}:{checkpoint}"
        encoder = load_encoder(checkpoint_spec)
        model, preprocess = encoder.model, encoder.preprocess  # type: ignore[attr-defined]
        detector = FailureDetector(memory_for(encoder.identity, encoder.dim), encoder, delta=0.92, k=5)
        session = detector.session("task_3")
        for _ in range(5):
            session.step(views)
        step_ms = median_ms(lambda session=session: session.step(views), 50)
        encode_ms = median_ms(lambda encoder=encoder: encoder.encode(list(views.values())), 50)

        def direct(model: object = model, preprocess: object = preprocess) -> None:
            with torch.inference_mode():
                tensor = torch.stack([preprocess(Image.fromarray(i)) for i in batch]).to(device)  # type: ignore[operator]
                model.encode_image(tensor).float().cpu()  # type: ignore[attr-defined]

        ours, theirs = [], []
        for _ in range(5):
            ours.append(median_ms(lambda encoder=encoder: encoder.encode(batch), 1))
            theirs.append(median_ms(direct, 1))
        print(
            f"{model_name} on {encoder.device}: per-frame detection (3 views, encode + retrieval over 15k entries) "  # type: ignore[attr-defined]
            f"{step_ms:.2f} ms (encode {encode_ms:.2f} ms); batch of 64: project {statistics.median(ours):.1f} ms vs "
            f"encode_image {statistics.median(theirs):.1f} ms, ratio {statistics.median(ours) / statistics.median(theirs):.3f}"
        )
        onnx_on_cuda(checkpoint_spec, views, batch, step_ms=encode_ms, batch_ms=statistics.median(ours))
    sys.stdout.flush()


def onnx_on_cuda(
    spec: str, views: dict[str, np.ndarray], batch: list[np.ndarray], *, step_ms: float, batch_ms: float
) -> None:
    """The fp32 ONNX export on the CUDA execution provider, beside torch's figures; skipped without it."""
    import onnxruntime

    from robofailring.encoders.device import CUDA
    from robofailring.encoders.exported import OnnxEncoder
    from robofailring.encoders.spec import EncoderSpec

    if CUDA not in onnxruntime.get_available_providers():
        print(
            f"  ONNX on CUDA: skipped, onnxruntime {onnxruntime.__version__} has no {CUDA} "
            f"(it has {', '.join(onnxruntime.get_available_providers())}); install onnxruntime-gpu to time it"
        )
        return
    with tempfile.TemporaryDirectory() as cache:
        encoder = OnnxEncoder(
            EncoderSpec.parse(spec).with_runtime("onnx"), device="cuda", cache_dir=Path(cache)
        )
        for _ in range(5):
            encoder.encode(list(views.values()))
        onnx_step = median_ms(lambda: encoder.encode(list(views.values())), 50)
        onnx_batch = median_ms(lambda: encoder.encode(batch), 5)
    print(
        f"  ONNX fp32 on {encoder.providers[0]}: 3-view encode {onnx_step:.2f} ms (torch {step_ms:.2f} ms, "
        f"{step_ms / onnx_step:.2f}×); batch of 64 {onnx_batch:.1f} ms (torch {batch_ms:.1f} ms, {batch_ms / onnx_batch:.2f}×)"
    )


if __name__ == "__main__":
    main()
