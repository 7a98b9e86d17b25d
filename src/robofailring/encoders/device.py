"""`--device`, checked once for every encoder kind and runtime: its form here, its presence where it runs.

A device is `cpu`, `cuda`, `cuda:N` or `mps` (`check_device_name`, asked where a detector's settings
are made and by `load_encoder`, so `npu`, `bogus:7` or `cuda:99999999999999999999` is one error before
anything is read, for every kind, `pixels` too). Whether it
is there is asked by what runs on it: torch (`pick_device`: no CUDA GPU, no GPU N, no Apple GPU), ONNX
Runtime (`providers_for`: no CUDA provider) and OpenVINO (the CPU only, `exported.session_opener`). A kind
without a network (`pixels`) runs in numpy on the CPU whatever the device.
"""

from __future__ import annotations

import re
from typing import Any, Final

from robofailring.errors import EncoderError, SettingError
from robofailring.extras import needs_extra

DEVICE_FORMS: Final[str] = "cpu, cuda, cuda:N (a GPU's index) or mps"
MAX_CUDA_INDEX: Final[int] = 2**31 - 1  # a CUDA device ordinal is a C int (ONNX Runtime's device_id too)
_DEVICE: Final[re.Pattern[str]] = re.compile(r"cpu|cuda(:[0-9]+)?|mps")


def check_device_name(device: str | None) -> str | None:
    """`device` when it has a device's form (`DEVICE_FORMS`) or is None (the default); SettingError otherwise."""
    if device is not None and not _DEVICE.fullmatch(device):
        raise SettingError(f"--device {device!r} is not a device robofailring runs on: use {DEVICE_FORMS}")
    if device is not None and device.startswith("cuda") and cuda_index(device) > MAX_CUDA_INDEX:
        raise SettingError(
            f"--device {device!r} is not a device robofailring runs on: a GPU's index is at most "
            f"{MAX_CUDA_INDEX:,} (CUDA numbers its GPUs with an int)"
        )
    return device


def cuda_index(device: str) -> int:
    """The GPU index of `cuda` (0) or `cuda:N`."""
    return int(device.partition(":")[2] or 0)


def pick_device(device: str | None = None) -> str:
    """The torch device to run on: `device` when torch has it here, else (None) `cuda` when available, else
    `cpu`; EncoderError naming the device when torch has no such GPU."""
    check_device_name(device)
    with needs_extra("clip"):
        import torch

    if device is None:
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device.startswith("cuda"):
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if count == 0:
            raise EncoderError(
                f"--device {device}: torch finds no CUDA GPU here (no GPU, no driver, or a CPU-only torch); "
                "use --device cpu"
            )
        if cuda_index(device) >= count:
            raise EncoderError(f"--device {device}: torch finds {count} CUDA GPU(s) here, numbered from 0")
    if device == "mps" and not torch.backends.mps.is_available():
        raise EncoderError("--device mps: torch finds no Apple GPU (MPS) here; use --device cpu")
    return device


CPU = "CPUExecutionProvider"
CUDA = "CUDAExecutionProvider"
Provider = str | tuple[str, dict[str, Any]]  # a provider, or one with its options (ONNX Runtime's form)


def providers_for(device: str | None) -> list[Provider]:
    """ONNX Runtime execution providers for a `--device`: CUDA first where it is asked for (on GPU N for
    `cuda:N`) or available; EncoderError where this ONNX Runtime cannot run on it."""
    check_device_name(device)
    with needs_extra("onnx"):
        import onnxruntime

    available = onnxruntime.get_available_providers()
    if device is not None and device.startswith("cuda"):
        if CUDA not in available:
            raise EncoderError(
                f"--device {device} asks for CUDA, but this ONNX Runtime has no CUDAExecutionProvider "
                f"(it has {', '.join(available)}); install onnxruntime-gpu in place of onnxruntime"
            )
        return [(CUDA, {"device_id": cuda_index(device)}), CPU]
    if device is not None and device != "cpu":
        raise EncoderError(f"--device {device}: ONNX Runtime runs on cpu or cuda[:N], not {device}")
    if device is None and CUDA in available:
        return [CUDA, CPU]
    return [CPU]
