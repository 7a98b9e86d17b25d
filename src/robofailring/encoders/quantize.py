"""int8 versions of an fp32 ONNX export: dynamic for ONNX Runtime, static and symmetric for OpenVINO.

`onnx-int8` (ONNX Runtime) is dynamic quantization: MatMul and Conv weights int8 per output channel,
activations quantized at run time, no calibration images. `openvino-int8` is static QDQ quantization
with uint8 activations (asymmetric) and 7-bit weights (per channel, symmetric, in -64..63): the one form
whose integer arithmetic every OpenVINO CPU kernel does exactly, so the same export gives the same
embeddings on AMX, AVX-512 VNNI and AVX2 CPUs (`STATIC_SCHEME`, docs/runtime.md "The same answer on
every CPU"). Its activation ranges come from `calibration_images()`, a fixed set of
procedural frames (smooth colour fields, flat and shaded shapes, sensor noise) rather than anybody's
data, so an export depends on the network alone and is made once.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Final, Literal

import numpy as np

from robofailring.errors import EncoderError
from robofailring.extras import needs_extra

QuantMode = Literal["dynamic", "static"]
CALIBRATION_FRAMES: Final[int] = 32  # part of the export's identity: a change is a new export
CALIBRATION_SEED: Final[int] = 0
#: The static form, part of the export's identity. int8 activations ran as int8 on AMX and were turned to
#: uint8 on VNNI (cosine 0.9988 between the two, enough to change a nearest neighbour), and full 8-bit
#: weights saturate AVX2's 16-bit pair sums (cosine 0.62 to the others); uint8 activations times 7-bit
#: weights fit every kernel's integer sums, which then agree to the bit.
STATIC_SCHEME: Final[str] = "u8-activations-w7-weights"


def calibration_images(
    count: int = CALIBRATION_FRAMES, size: int = 224, seed: int = CALIBRATION_SEED
) -> list[np.ndarray]:
    """`count` RGB uint8 frames of `size` px, the same on every machine: a smooth colour field under
    three to eight flat or shaded rectangles and discs, with sensor noise (the statistics of a camera
    frame of objects on a table, not of any dataset)."""
    rng = np.random.default_rng(seed)
    rows, columns = np.mgrid[0:size, 0:size] / size
    frames = []
    for _ in range(count):
        corners = rng.uniform(0, 255, (2, 2, 3))
        top = corners[0, 0] * (1 - columns[..., None]) + corners[0, 1] * columns[..., None]
        bottom = corners[1, 0] * (1 - columns[..., None]) + corners[1, 1] * columns[..., None]
        frame = top * (1 - rows[..., None]) + bottom * rows[..., None]
        for _ in range(int(rng.integers(3, 9))):
            x, y = rng.uniform(0, 1, 2)
            width, height = rng.uniform(0.02, 0.4, 2)
            if rng.random() < 0.5:
                inside = (abs(columns - x) < width / 2) & (abs(rows - y) < height / 2)
            else:
                inside = ((columns - x) / width) ** 2 + ((rows - y) / height) ** 2 < 0.25
            shade = 1 + 0.3 * (rows - y)[..., None]
            frame = np.where(inside[..., None], rng.uniform(0, 255, 3) * shade, frame)
        frame = frame + rng.normal(0, 6, frame.shape)
        frames.append(np.clip(frame, 0, 255).astype(np.uint8))
    return frames


def quantize(
    source: Path, target: Path, *, mode: QuantMode = "dynamic", calibration: np.ndarray | None = None
) -> None:
    """Quantize the fp32 ONNX file `source` to int8 at `target`: dynamic (weights int8 ahead, activations
    at run time), or static QDQ (`STATIC_SCHEME`) with activation ranges from `calibration` pixels (N, 3, S, S)."""
    with needs_extra("onnx"):
        from onnxruntime.quantization import (
            CalibrationDataReader,
            QuantFormat,
            QuantType,
            quantize_dynamic,
            quantize_static,
        )

    logging.getLogger("root").setLevel(logging.ERROR)  # ORT's advice to pre-process goes to the root logger
    if mode == "dynamic":
        quantize_dynamic(str(source), str(target), weight_type=QuantType.QInt8, per_channel=True)
        return
    if calibration is None or len(calibration) == 0:
        raise EncoderError("static quantization needs calibration pixels")
    batches = [{"pixels": calibration[start : start + 8]} for start in range(0, len(calibration), 8)]

    class Reader(CalibrationDataReader):
        def __init__(self) -> None:
            self._batches = iter(batches)

        def get_next(self) -> dict[str, np.ndarray] | None:
            return next(self._batches, None)

    quantize_static(
        str(source),
        str(target),
        Reader(),
        quant_format=QuantFormat.QDQ,
        per_channel=True,
        reduce_range=True,  # 7-bit weights: u8 × s7 pairs never saturate AVX2's 16-bit sums
        activation_type=QuantType.QUInt8,
        weight_type=QuantType.QInt8,
        extra_options={"ActivationSymmetric": False, "WeightSymmetric": True},
    )
