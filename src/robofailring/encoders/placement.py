"""Where an encoder runs: `EncoderPlacement` (device, runtime, embedding cache, Ray cluster), one value held by
every job that encodes, the detectors' (`DetectorConfig.placement`) and the memory builds' alike."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Final

from robofailring.encoders import open_encoder
from robofailring.encoders.cache import CachedEncoder
from robofailring.encoders.device import check_device_name


@dataclass(frozen=True)
class EncoderPlacement:
    """Where an encoder runs and keeps what it encoded; it never chooses the encoder (a memory's recipe, or the
    memory itself, does)."""

    device: str | None = None  # cpu, cuda[:N] or mps (encoders/device.py; default: cuda when available)
    runtime: str | None = (
        None  # torch, onnx, onnx-int8 or openvino-int8 (default: the spec's own, else torch)
    )
    cache_dir: Path | None = None  # embedding cache (default $ROBOFAILRING_CACHE, else ~/.cache/robofailring)
    ray: str | None = None  # a Ray cluster's address: frames a job prefetches decoded and encoded there

    def __post_init__(self) -> None:  # a bad device fails before anything is read
        check_device_name(self.device)

    def open(self, spec: str) -> CachedEncoder:
        """The encoder `spec` placed here: on this device, runtime and cache, and this Ray cluster (which
        encodes what a job prefetches, docs/ray.md)."""
        return open_encoder(
            spec,
            device=self.device,
            cache_dir=Path(self.cache_dir) if self.cache_dir is not None else None,
            runtime=self.runtime,
            ray=self.ray,
        )


DEFAULT_PLACEMENT: Final[EncoderPlacement] = EncoderPlacement()  # every setting at its default
