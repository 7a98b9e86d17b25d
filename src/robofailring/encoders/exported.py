"""`OnnxEncoder`: an open_clip or trained encoder run through ONNX Runtime from its cached export.

`spec@onnx` runs the fp32 export, `spec@onnx-int8` the int8 one (docs/runtime.md). The identity is the
torch encoder's: a memory built in torch is queried through ONNX Runtime, and the other way round (the
embeddings agree within cosine 0.999 in fp32 and 0.99 in int8, tests/encoders/test_exported.py). The
embedding cache keeps each runtime's numbers apart (`cache_identity`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from robofailring.encoders.base import l2_normalize
from robofailring.encoders.export import Export, discard_export, ensure_export
from robofailring.encoders.spec import EncoderSpec
from robofailring.encoders.trained import prepare_images
from robofailring.errors import EncoderError
from robofailring.extras import needs_extra

CPU = "CPUExecutionProvider"
CUDA = "CUDAExecutionProvider"


def providers_for(device: str | None) -> list[str]:
    """ONNX Runtime execution providers for a `--device`: CUDA first where it is asked for or available."""
    with needs_extra("onnx"):
        import onnxruntime

    available = onnxruntime.get_available_providers()
    if device is not None and device.startswith("cuda"):
        if CUDA not in available:
            raise EncoderError(
                f"--device {device} asks for CUDA, but this ONNX Runtime has no CUDAExecutionProvider "
                f"(it has {', '.join(available)}); install onnxruntime-gpu in place of onnxruntime"
            )
        return [CUDA, CPU]
    if device is None and CUDA in available:
        return [CUDA, CPU]
    return [CPU]


def open_session(model: Path, providers: Sequence[str], *, threads: int | None = None) -> Any:
    """An ONNX Runtime session on `model` (intra-op threads: `threads`, else ORT's own choice)."""
    with needs_extra("onnx"):
        import onnxruntime

    options = onnxruntime.SessionOptions()
    options.graph_optimization_level = onnxruntime.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.inter_op_num_threads = 1
    if threads:
        options.intra_op_num_threads = threads
    options.log_severity_level = 3  # errors only: ORT's per-node placement notes are not for users
    return onnxruntime.InferenceSession(str(model), options, providers=list(providers))


class Preprocess:
    """The pixels an export expects, from RGB uint8 images, exactly as the torch encoder prepares them."""

    def __init__(self, description: dict[str, Any]) -> None:
        self.kind = description.get("kind")
        if self.kind == "open_clip":
            with needs_extra("clip"):
                from open_clip.transform import PreprocessCfg, image_transform_v2

            fields = {key: value for key, value in description.items() if key != "kind"}
            fields["size"] = tuple(fields["size"]) if isinstance(fields["size"], list) else fields["size"]
            self._transform = image_transform_v2(PreprocessCfg(**fields), is_train=False)
        elif self.kind == "square":
            self._size = int(description["size"])
            self._mean = np.asarray(description["mean"], dtype=np.float32).reshape(1, 3, 1, 1)
            self._std = np.asarray(description["std"], dtype=np.float32).reshape(1, 3, 1, 1)
        else:
            raise EncoderError(f"unknown preprocessing {self.kind!r} in an ONNX export")

    def __call__(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if self.kind == "open_clip":
            with needs_extra("clip"):
                from PIL import Image

            return np.stack([self._transform(Image.fromarray(image)).numpy() for image in images])
        batch = prepare_images(images, self._size).transpose(0, 3, 1, 2).astype(np.float32) / np.float32(
            255.0
        )
        return np.ascontiguousarray((batch - self._mean) / self._std, dtype=np.float32)


class OnnxEncoder:
    """An exported encoder on ONNX Runtime (see the module docstring); made by `load_encoder(spec@onnx…)`."""

    def __init__(
        self,
        spec: EncoderSpec,
        *,
        device: str | None = None,
        cache_dir: Path | None = None,
        threads: int | None = None,
        batch_size: int = 64,
    ) -> None:
        if spec.runtime == "torch":
            raise EncoderError(f"{spec} runs in torch, not ONNX Runtime")
        providers = providers_for(device)
        export = ensure_export(spec, cache_dir)
        try:
            session = open_session(export.model, providers, threads=threads)
        except Exception as error:  # ORT raises its own Fail/InvalidProtobuf types for a broken file
            _warn_reexport(export, error)
            discard_export(export.folder)
            export = ensure_export(spec, cache_dir)
            session = open_session(export.model, providers, threads=threads)
        self.export: Export = export
        self.session = session
        self.runtime = spec.runtime
        self._preprocess = Preprocess(export.preprocess)
        self._batch_size = batch_size

    @property
    def identity(self) -> str:
        return self.export.identity

    @property
    def dim(self) -> int:
        return self.export.dim

    @property
    def providers(self) -> list[str]:
        """The execution providers the session runs on, in order of preference."""
        return list(self.session.get_providers())

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        if len(images) == 0:
            return np.zeros((0, self.dim), dtype=np.float32)
        outputs = [
            self.session.run(None, {"pixels": self._preprocess(images[start : start + self._batch_size])})[0]
            for start in range(0, len(images), self._batch_size)
        ]
        return l2_normalize(np.concatenate(outputs))


def _warn_reexport(export: Export, error: Exception) -> None:
    first = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
    logging.getLogger("robofailring").warning(
        "warning: ONNX Runtime cannot read the cached export %s (%s); exporting it again",
        export.folder,
        first,
    )
