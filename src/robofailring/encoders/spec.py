"""`EncoderSpec`: an encoder spec string parsed once, at the edge, with its canonical, portable and slug forms.

The forms are `pixels`, `open_clip:<model>[:<pretrained tag or checkpoint path>]` and `trained:<DIR>`
(docs/architecture.md, encoders/). Everything that reads a spec string goes through `EncoderSpec.parse`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from robofailring.errors import EncoderError

ENCODER_SPECS_HELP = (
    "`pixels` (weight-free), `open_clip:<model>[:<pretrained tag or checkpoint path>]`, "
    "e.g. `open_clip:ViT-B-32:openai` or `open_clip:ViT-L-14:/models/vit-l-14.pt`, "
    "or `trained:<DIR>` (a folder written by `robofailring train-encoder`)"
)

Kind = Literal["pixels", "open_clip", "trained"]


@dataclass(frozen=True)
class EncoderSpec:
    """One encoder spec: `kind` plus the open_clip model and weights, or the trained folder."""

    kind: Kind
    model: str = ""  # open_clip: a model name or a model-config JSON path
    weights: str = ""  # open_clip: a pretrained tag or a checkpoint path ("" for open_clip's default)
    directory: str = ""  # trained: the folder written by `robofailring train-encoder`

    @classmethod
    def parse(cls, spec: str | EncoderSpec) -> EncoderSpec:
        """The spec a string names; an EncoderError names the string and lists the forms."""
        if isinstance(spec, EncoderSpec):
            return spec
        text = spec.strip()
        if text == "pixels":
            return cls("pixels")
        kind, sep, rest = text.partition(":")
        if sep and kind == "open_clip":
            model, _, weights = rest.partition(":")
            if not model:
                raise EncoderError(f"encoder spec {text!r} names no model; expected {ENCODER_SPECS_HELP}")
            return cls("open_clip", model=model, weights=weights)
        if sep and kind == "trained":
            if not rest:
                raise EncoderError(f"encoder spec {text!r} names no folder; expected {ENCODER_SPECS_HELP}")
            return cls("trained", directory=rest)
        raise EncoderError(f"unknown encoder spec {text!r}; expected {ENCODER_SPECS_HELP}")

    def __str__(self) -> str:
        if self.kind == "open_clip":
            return f"open_clip:{self.model}" + (f":{self.weights}" if self.weights else "")
        if self.kind == "trained":
            return f"trained:{self.directory}"
        return "pixels"

    def portable(self) -> EncoderSpec:
        """The spec a memory records: a `trained:` folder or an open_clip checkpoint or config file as
        an absolute path, so the memory finds its encoder again from any working directory."""
        if self.kind == "trained":
            return EncoderSpec("trained", directory=str(Path(self.directory).resolve()))
        if self.kind == "open_clip":
            model, weights = (
                str(Path(part).resolve()) if Path(part).is_file() else part
                for part in (self.model, self.weights)
            )
            return EncoderSpec("open_clip", model=model, weights=weights)
        return self

    @staticmethod
    def slug(identity: str) -> str:
        """A short path-safe name for an encoder identity, e.g. `vit-b-32` or `pixels`."""
        kind, _, rest = identity.partition(":")
        if kind == "open_clip":
            return rest.partition(":")[0].lower().replace("/", "-")
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
