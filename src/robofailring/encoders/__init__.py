"""Encoders: `load_encoder(spec)` for `pixels` and `open_clip:<model>[:<tag or checkpoint>]`."""

from __future__ import annotations

from robofailring.encoders.base import Encoder, l2_normalize
from robofailring.encoders.cache import CachedEncoder, EmbeddingCache, default_cache_dir
from robofailring.errors import EncoderError

ENCODER_SPECS_HELP = (
    "`pixels` (weight-free) or `open_clip:<model>[:<pretrained tag or checkpoint path>]`, "
    "e.g. `open_clip:ViT-B-32:openai` or `open_clip:ViT-L-14:/models/vit-l-14.pt`"
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
    raise EncoderError(f"unknown encoder spec {spec!r}; expected {ENCODER_SPECS_HELP}")


def encoder_slug(identity: str) -> str:
    """A short path-safe name for an encoder identity, e.g. `vit-b-32` or `pixels`."""
    if identity.startswith("open_clip:"):
        return identity.split(":")[1].lower().replace("/", "-")
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
]
