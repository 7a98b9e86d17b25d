"""`EncoderSpec`: an encoder spec string parsed once, at the edge, with its canonical, portable and slug forms.

The forms are `pixels`, `open_clip:<model>[:<pretrained tag or checkpoint path>]`, `timm:<model>[:<checkpoint>]`
and `trained:<DIR>`
(docs/architecture.md, encoders/), each optionally ending in `@<runtime>`: `@onnx` or `@onnx-int8` run the
network exported to ONNX Runtime, `@openvino-int8` its static int8 form on OpenVINO (docs/runtime.md),
`@torch` (the default) runs it in torch. Everything
that reads a spec string goes through `EncoderSpec.parse`; `--runtime` sets the same field (`with_runtime`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Final, Literal, cast

from robofailring.errors import EncoderError

Runtime = Literal["torch", "onnx", "onnx-int8", "openvino-int8"]
RUNTIMES: Final[tuple[Runtime, ...]] = ("torch", "onnx", "onnx-int8", "openvino-int8")

ENCODER_SPECS_HELP = (
    "`pixels` (weight-free), `open_clip:<model>[:<pretrained tag or checkpoint path>]`, "
    "e.g. `open_clip:ViT-B-32:openai` or `open_clip:ViT-L-14:/models/vit-l-14.pt`, "
    "`timm:<model>[:<checkpoint path>]` (a timm backbone's pooled features, e.g. `timm:efficientnet_lite0:/models/"
    "lite0.pth`), or `trained:<DIR>` (a folder written by `robofailring train-encoder`); an open_clip, timm or trained spec "
    "may end in `@onnx` or `@onnx-int8` (run through ONNX Runtime), `@openvino-int8` (static int8 on OpenVINO, the fastest "
    "on a CPU) or `@torch` (the default)"
)

Kind = Literal["pixels", "open_clip", "timm", "trained"]


@dataclass(frozen=True)
class EncoderSpec:
    """One encoder spec: `kind` plus the open_clip model and weights, or the trained folder."""

    kind: Kind
    model: str = ""  # open_clip: a model name or a model-config JSON path; timm: a model name
    weights: str = ""  # open_clip: a pretrained tag or a checkpoint path ("" for open_clip's default); timm: a checkpoint
    directory: str = ""  # trained: the folder written by `robofailring train-encoder`
    runtime: Runtime = (
        "torch"  # what runs the network: torch, or its ONNX export (fp32 or int8; ORT or OpenVINO)
    )

    @classmethod
    def parse(cls, spec: str | EncoderSpec) -> EncoderSpec:
        """The spec a string names; an EncoderError names the string and lists the forms."""
        if isinstance(spec, EncoderSpec):
            return spec
        whole = spec.strip()
        text, at, runtime = whole.rpartition("@")
        if not at or runtime not in RUNTIMES:  # an `@` that names no runtime is part of a path
            return cls._parse_network(whole, whole)
        network = cls._parse_network(text, whole)
        try:
            return network.with_runtime(runtime)
        except EncoderError as error:
            raise EncoderError(f"encoder spec {whole!r}: {error}") from None

    def with_runtime(self, runtime: str | None) -> EncoderSpec:
        """This spec run by `runtime` (None keeps its own); an EncoderError for an unknown runtime or for
        `pixels`, which has no network to export."""
        if runtime is None or runtime == self.runtime:
            return self
        if runtime not in RUNTIMES:
            raise EncoderError(f"unknown runtime {runtime!r}; expected one of {', '.join(RUNTIMES)}")
        if self.kind == "pixels" and runtime != "torch":
            raise EncoderError(
                f"the pixels encoder has no network to run through {runtime}; runtimes apply to "
                "open_clip, timm and trained encoders"
            )
        return replace(self, runtime=cast(Runtime, runtime))

    @classmethod
    def _parse_network(cls, text: str, whole: str) -> EncoderSpec:
        if text == "pixels":
            return cls("pixels")
        kind, sep, rest = text.partition(":")
        if sep and kind == "open_clip":
            model, _, weights = rest.partition(":")
            if not model:
                raise EncoderError(f"encoder spec {whole!r} names no model; expected {ENCODER_SPECS_HELP}")
            return cls("open_clip", model=model, weights=weights)
        if sep and kind == "timm":
            model, _, weights = rest.partition(":")
            if not model:
                raise EncoderError(f"encoder spec {whole!r} names no model; expected {ENCODER_SPECS_HELP}")
            return cls("timm", model=model, weights=weights)
        if sep and kind == "trained":
            if not rest:
                raise EncoderError(f"encoder spec {whole!r} names no folder; expected {ENCODER_SPECS_HELP}")
            return cls("trained", directory=rest)
        raise EncoderError(f"unknown encoder spec {whole!r}; expected {ENCODER_SPECS_HELP}")

    def __str__(self) -> str:
        if self.kind in ("open_clip", "timm"):
            network = f"{self.kind}:{self.model}" + (f":{self.weights}" if self.weights else "")
        elif self.kind == "trained":
            network = f"trained:{self.directory}"
        else:
            return "pixels"
        at, _, last = network.rpartition("@")
        named = at and last in RUNTIMES  # a path ending in `@onnx` needs its `@torch` said
        return network if self.runtime == "torch" and not named else f"{network}@{self.runtime}"

    def portable(self) -> EncoderSpec:
        """The spec a memory records: a `trained:` folder or an open_clip checkpoint or config file as
        an absolute path, so the memory finds its encoder again from any working directory."""
        if self.kind == "trained":
            return replace(self, directory=str(Path(self.directory).resolve()))
        if self.kind in ("open_clip", "timm"):
            model, weights = (
                str(Path(part).resolve()) if Path(part).is_file() else part
                for part in (self.model, self.weights)
            )
            return replace(self, model=model, weights=weights)
        return self

    @staticmethod
    def slug(identity: str) -> str:
        """A short path-safe name for an encoder identity, e.g. `vit-b-32` or `pixels`; an identity with
        a runtime (`base.cache_identity`, `…@onnx-int8`) keeps it, e.g. `vit-b-32-onnx-int8`."""
        network, at, runtime = identity.rpartition("@")
        if at and runtime in RUNTIMES:
            return f"{EncoderSpec.slug(network)}-{runtime}"
        kind, _, rest = identity.partition(":")
        if kind == "open_clip":
            return rest.partition(":")[0].lower().replace("/", "-")
        if kind == "timm":
            return "timm-" + rest.partition(":")[0].lower().replace("/", "-").replace(".", "-")
        if kind == "trained":  # trained:<arch>:<weights digest>; two trained ones stay apart
            return f"trained-{identity.rsplit(':', 1)[-1][:8]}"
        return identity.split("-")[0].lower()

    @staticmethod
    def for_memory(identity: str, recorded: object) -> str:
        """The spec that reproduces a memory's encoder `identity`, given the `encoder_spec` its manifest
        recorded (None in memories older than that field)."""
        if identity.startswith("pixels"):
            return "pixels"
        if isinstance(recorded, str):
            return recorded
        if ":file-" in identity:
            model = identity.partition(":")[2].partition(":")[0]
            raise EncoderError(
                f"this memory was built with {identity} (a checkpoint file) and does not record where that file is; "
                f"pass --encoder open_clip:{model}:/path/to/the/same/checkpoint"
            )
        return identity
