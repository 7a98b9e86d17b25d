"""Encoders: `load_encoder(spec)` for `pixels`, `open_clip:<model>[:<tag or checkpoint>]` and `trained:<DIR>`."""

from __future__ import annotations

from pathlib import Path

from robofailring.encoders.base import Encoder, l2_normalize
from robofailring.encoders.cache import CachedEncoder, EmbeddingCache, default_cache_dir
from robofailring.errors import EncoderError

ENCODER_SPECS_HELP = (
    "`pixels` (weight-free), `open_clip:<model>[:<pretrained tag or checkpoint path>]`, "
    "e.g. `open_clip:ViT-B-32:openai` or `open_clip:ViT-L-14:/models/vit-l-14.pt`, "
    "or `trained:<DIR>` (a folder written by `robofailring train-encoder`)"
)


def load_encoder(spec: str, *, device: str | None = None) -> Encoder:
    """Build an encoder from a spec string (see ENCODER_SPECS_HELP)."""
    spec = spec.strip()
    if spec == "pixels":
        from robofailring.encoders.pixels import PixelEncoder

        return PixelEncoder()
    if spec.startswith("open_clip:"):
        rest = spec[len("open_clip:") :]
        model, _, weights = rest.partition(":")
        if not model:
            raise EncoderError(f"encoder spec {spec!r} names no model; expected {ENCODER_SPECS_HELP}")
        from robofailring.encoders.openclip import OpenClipEncoder

        return OpenClipEncoder(model, weights, device=device)
    if spec.startswith("trained:"):
        directory = spec[len("trained:") :]
        if not directory:
            raise EncoderError(f"encoder spec {spec!r} names no folder; expected {ENCODER_SPECS_HELP}")
        from robofailring.encoders.trained import TrainedEncoder

        return TrainedEncoder(Path(directory), device=device)
    raise EncoderError(f"unknown encoder spec {spec!r}; expected {ENCODER_SPECS_HELP}")


def portable_spec(spec: str) -> str:
    """The spec a memory records: a `trained:` folder or an open_clip checkpoint file as an absolute
    path, so the memory finds its encoder again from any working directory."""
    spec = spec.strip()
    if spec.startswith("trained:"):
        return f"trained:{Path(spec[len('trained:') :]).resolve()}"
    if spec.startswith("open_clip:"):
        model, _, weights = spec[len("open_clip:") :].partition(":")
        parts = [Path(part).resolve() if Path(part).is_file() else part for part in (model, weights)]
        return "open_clip:" + ":".join(str(part) for part in parts if str(part))
    return spec


def encoder_slug(identity: str) -> str:
    """A short path-safe name for an encoder identity, e.g. `vit-b-32` or `pixels`."""
    if identity.startswith("open_clip:"):
        return identity.split(":")[1].lower().replace("/", "-")
    if identity.startswith("trained:"):  # trained:<arch>:<weights digest>; two trained ones stay apart
        return f"trained-{identity.rsplit(':', 1)[-1][:8]}"
    return identity.split("-")[0].lower()


__all__ = [
    "ENCODER_SPECS_HELP",
    "CachedEncoder",
    "EmbeddingCache",
    "Encoder",
    "default_cache_dir",
    "encoder_slug",
    "l2_normalize",
    "load_encoder",
    "portable_spec",
]
