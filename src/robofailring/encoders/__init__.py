"""Encoders: `load_encoder(spec)` for `pixels`, `open_clip:<model>[:<tag or checkpoint>]`, `timm:<model>[:<checkpoint>]`
and `trained:<DIR>`, each kind one module registered in `spec.py`; the last three in torch or, with a `@runtime`, from their
export on ONNX Runtime or OpenVINO (docs/runtime.md)."""

from __future__ import annotations

import functools
from pathlib import Path

from robofailring.encoders.base import Encoder, l2_normalize
from robofailring.encoders.cache import CachedEncoder, EmbeddingCache, cache_identity, default_cache_dir
from robofailring.encoders.device import check_device_name
from robofailring.encoders.spec import ENCODER_SPECS_HELP, EncoderSpec, kind_of


def load_encoder(
    spec: str | EncoderSpec, *, device: str | None = None, cache_dir: Path | None = None
) -> Encoder:
    """Build an encoder from a spec string or EncoderSpec (see ENCODER_SPECS_HELP); a new one every call.

    An ONNX runtime exports the network into `cache_dir` (default `default_cache_dir()`) the first time.
    """
    return _load(EncoderSpec.parse(spec), device, cache_dir)


def _load(spec: EncoderSpec, device: str | None, cache_dir: Path | None) -> Encoder:
    if (
        spec.runtime != "torch"
    ):  # the runtime layer: the kind's network from its export, on the device it checks
        from robofailring.encoders.exported import OnnxEncoder

        return OnnxEncoder(spec, device=device, cache_dir=cache_dir)
    check_device_name(device)
    return kind_of(spec).load(spec, device)


def open_encoder(
    spec: str | EncoderSpec,
    *,
    device: str | None = None,
    cache_dir: Path | None = None,
    runtime: str | None = None,
    ray: str | None = None,
) -> CachedEncoder:
    """The one way jobs open an encoder: its model is loaded once per process for a (spec, device).

    The memo key is the spec's portable form (with its runtime), the device, the cache dir of an
    ONNX runtime (where its export is) and the modification times of the files
    the spec names, so a folder retrained or a checkpoint rewritten in place is loaded again. The
    embedding cache in `cache_dir` is opened afresh on every call (as a new process would open it).
    `runtime` (`--runtime`) overrides the spec's own `@runtime` (`EncoderSpec.with_runtime`).
    `ray`: the address of a Ray cluster that encodes what the jobs prefetch (docs/ray.md).
    """
    portable = EncoderSpec.parse(spec).with_runtime(runtime).portable()
    exports = cache_dir if portable.runtime != "torch" else None  # where an ONNX runtime's export is
    encoder = _loaded_encoder(portable, device, exports, portable.files_stamp())
    backend = None
    if ray is not None:
        from robofailring.encoders.ray_backend import RayBackend

        backend = RayBackend(ray, spec=str(portable), identity=encoder.identity, device=device)
    return CachedEncoder(encoder, cache_dir=cache_dir, backend=backend)


@functools.lru_cache(maxsize=8)
def _loaded_encoder(
    spec: EncoderSpec, device: str | None, cache_dir: Path | None, stamp: tuple[int, ...]
) -> Encoder:
    del stamp  # only part of the key
    return _load(spec, device, cache_dir)


def portable_spec(spec: str | EncoderSpec) -> str:
    """The spec a memory records (`EncoderSpec.portable`), as a string."""
    return str(EncoderSpec.parse(spec).portable())


def encoder_slug(identity: str) -> str:
    """A short path-safe name for an encoder identity (`EncoderSpec.slug`)."""
    return EncoderSpec.slug(identity)


__all__ = [
    "ENCODER_SPECS_HELP",
    "CachedEncoder",
    "EmbeddingCache",
    "Encoder",
    "EncoderSpec",
    "cache_identity",
    "default_cache_dir",
    "encoder_slug",
    "l2_normalize",
    "load_encoder",
    "open_encoder",
    "portable_spec",
]
