"""The encoder kinds: a spec's kind names the one module that knows its network (docs/architecture.md).

Each kind module (`pixels.py`, `openclip.py`, `timm_backbone.py`, `trained.py`) has three functions:
`load(spec, device)`, its encoder in torch (or numpy); `export_identity(spec)`, its identity and what an
export of it is made from, found without loading the network; and `network(spec)`, the torch module an
export traces (`Network`). The runtimes (`exported.py`: ONNX Runtime, OpenVINO) and the embedding cache
(`cache.py`) are layers around any kind: `load_encoder` picks the layer, `kind_of` the kind.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Final, Protocol, cast

from robofailring.encoders.base import Encoder
from robofailring.encoders.spec import EncoderSpec

KIND_MODULES: Final[dict[str, str]] = {
    "pixels": "robofailring.encoders.pixels",
    "open_clip": "robofailring.encoders.openclip",
    "timm": "robofailring.encoders.timm_backbone",
    "trained": "robofailring.encoders.trained",
}


@dataclass(frozen=True)
class Network:
    """What an export traces: the torch module from normalised pixels (N, 3, side, side) to the
    unnormalised embedding, with the preprocessing that makes those pixels, the identity and the width."""

    module: Any
    side: int
    preprocess: dict[
        str, Any
    ]  # {"kind": "open_clip", ...open_clip's PreprocessCfg} or {"kind": "square", ...}
    identity: str
    dim: int


class Kind(Protocol):
    """What each kind module provides (module-level functions)."""

    def load(self, spec: EncoderSpec, device: str | None) -> Encoder: ...

    def export_identity(self, spec: EncoderSpec) -> tuple[str, str]: ...

    def network(self, spec: EncoderSpec) -> Network: ...


def kind_of(spec: EncoderSpec) -> Kind:
    """The module of `spec`'s kind, imported on first use (torch only where a kind needs it)."""
    return cast(Kind, importlib.import_module(KIND_MODULES[spec.kind]))
