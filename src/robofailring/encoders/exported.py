"""`OnnxEncoder`: an open_clip, timm or trained encoder run from its cached ONNX export.

`spec@onnx` runs the fp32 export and `spec@onnx-int8` its dynamic int8 form on ONNX Runtime;
`spec@openvino-int8` runs its static int8 form on OpenVINO's CPU plugin (docs/runtime.md). The identity
is the torch encoder's: a memory built in torch is queried through an export, and the other way round
(the embeddings agree within cosine 0.999 in fp32 and 0.98 in int8, tests/encoders/test_exported.py).
The embedding cache keeps each runtime's numbers apart (`cache_identity`).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.encoders.base import l2_normalize
from robofailring.encoders.device import Provider, check_device_name, providers_for
from robofailring.encoders.export import Export, discard_export, ensure_export
from robofailring.encoders.preprocess import Preprocess
from robofailring.encoders.spec import EncoderSpec
from robofailring.errors import EncoderError
from robofailring.extras import needs_extra


def open_session(model: Path, providers: Sequence[Provider], *, threads: int | None = None) -> Any:
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


OPENVINO_CPU = "OpenVINO CPU"
#: The precision OpenVINO runs the layers outside the int8 ones in. Its CPU plugin picks bf16 by itself
#: where the CPU has AMX or AVX-512 BF16 and f32 elsewhere, so the same export gave other embeddings (and
#: other neighbours) on an Intel Xeon than on an AMD one; asked for explicitly, every CPU agrees.
OPENVINO_PRECISION: Final[str] = "f32"


class OpenVinoSession:
    """An export compiled by OpenVINO for the CPU, run as an ONNX Runtime session is (`run`, `get_providers`);
    its float layers in `OPENVINO_PRECISION` whatever the CPU would choose."""

    def __init__(self, model: Path, *, threads: int | None = None) -> None:
        with needs_extra("openvino"):
            import openvino

        config: dict[str, Any] = {
            "PERFORMANCE_HINT": "LATENCY",
            "INFERENCE_PRECISION_HINT": OPENVINO_PRECISION,
        }
        if threads:
            config["INFERENCE_NUM_THREADS"] = threads
        self._compiled = openvino.Core().compile_model(str(model), "CPU", config)
        self._request = self._compiled.create_infer_request()
        self._lock = threading.Lock()  # one infer request: one run at a time

    @property
    def precision(self) -> str:
        """The precision the compiled model runs its float layers in, as OpenVINO reports it (`f32`)."""
        return str(self._compiled.get_property("INFERENCE_PRECISION_HINT").to_string())

    @property
    def input_shape(self) -> list[int | None]:
        """The model's input shape, None for a side it leaves open (the batch)."""
        shape = self._compiled.inputs[0].get_partial_shape()
        return [side.get_length() if side.is_static else None for side in shape]

    def run(self, _outputs: None, feeds: dict[str, np.ndarray]) -> list[np.ndarray]:
        with self._lock:
            return [np.array(self._request.infer({0: feeds["pixels"]})[0], dtype=np.float32)]

    def get_providers(self) -> list[str]:
        return [OPENVINO_CPU]


def session_opener(runtime: str, device: str | None, threads: int | None) -> Callable[[Path], Any]:
    """What opens an export of `runtime` on `device`: an ONNX Runtime session, or OpenVINO's (CPU only)."""
    if runtime == "openvino-int8":
        if check_device_name(device) not in (None, "cpu"):
            raise EncoderError(
                f"--runtime openvino-int8 runs on the CPU (OpenVINO), not on --device {device}; on a GPU use "
                "--runtime onnx or torch"
            )
        return lambda model: OpenVinoSession(model, threads=threads)
    providers = providers_for(device)
    return lambda model: open_session(model, providers, threads=threads)


class OnnxEncoder:
    """An exported encoder on ONNX Runtime or OpenVINO (see the module docstring); made by
    `load_encoder(spec@onnx…)`."""

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
            raise EncoderError(f"{spec} runs in torch, not from an export")
        open_model = session_opener(spec.runtime, device, threads)
        export = ensure_export(spec, cache_dir)
        preprocess = Preprocess(export.preprocess)  # checked with the export: only a missing extra stops it
        try:
            session = open_model(export.model)
            _check_sides(export, session, preprocess)  # before a frame batch is sized by the preprocessing
        except Exception as error:  # ORT and OpenVINO raise their own types for a broken file
            _warn_reexport(export, error)
            discard_export(export.folder)
            export = ensure_export(spec, cache_dir)
            preprocess = Preprocess(export.preprocess)
            session = open_model(export.model)
        self.export: Export = export
        self.identity: str = export.identity  # the torch encoder's (the module docstring)
        self.dim: int = export.dim
        self.session = session
        self.runtime = spec.runtime
        self._preprocess = preprocess
        self._batch_size = batch_size

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


def _check_sides(export: Export, session: Any, preprocess: Preprocess) -> None:
    """EncoderError unless the export's recorded preprocessing makes pixels of its model's fixed input side."""
    if isinstance(session, OpenVinoSession):
        shape = session.input_shape
    else:
        shape = list(session.get_inputs()[0].shape)
    model = tuple(shape[-2:])
    made = preprocess.sides
    if all(isinstance(side, int) for side in model) and model != made:
        raise EncoderError(
            f"the cached ONNX export {export.folder} is incomplete or corrupt (its preprocessing makes "
            f"{made[0]}x{made[1]} px, its model takes {model[0]}x{model[1]})"
        )


def _warn_reexport(export: Export, error: Exception) -> None:
    if isinstance(error, EncoderError):
        logging.getLogger("robofailring").warning("warning: %s; exporting it again", error)
        return
    first = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
    logging.getLogger("robofailring").warning(
        "warning: the runtime cannot read the cached export %s (%s); exporting it again",
        export.folder,
        first,
    )
