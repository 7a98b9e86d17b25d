"""`EncoderSpec`: an encoder spec string parsed once, at the edge, with its canonical, portable and slug forms;
and the encoder kinds it names, each registered once here (`EncoderKind`, `register`).

A spec is a kind's name followed, for a kind that takes them, by `:` and its arguments (`pixels`,
`open_clip:<model>[:<pretrained tag or checkpoint path>]`, `timm:<model>[:<checkpoint>]`, `trained:<DIR>`:
`ENCODER_SPECS_HELP`), optionally ending in `@<runtime>`: `@onnx` or `@onnx-int8` run the network exported to
ONNX Runtime, `@openvino-int8` its static int8 form on OpenVINO (docs/runtime.md), `@torch` (the default) runs
it in torch. Everything that reads a spec string goes through `EncoderSpec.parse`; `--runtime` sets the same
field (`with_runtime`).

Each kind is registered once here: its record (`EncoderKind`) says how its spec reads and prints, its help,
the slug of its identities and whether a runtime can export it, and names its module, imported on first use
(`kind_of`), which has three functions (`Kind`): `load(spec, device)`, its encoder in torch (or numpy);
`export_identity(spec)`, its identity and what an export of it is made from, found without loading the network;
and `network(spec)`, the torch module an export traces (`Network`). The runtimes (`exported.py`: ONNX Runtime,
OpenVINO) and the embedding cache (`cache.py`) are layers around any kind. A new kind is its module and one
`register` here (docs/architecture.md, "Adding an encoder kind"); nothing else names a kind.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Final, Literal, Protocol, cast

from robofailring.encoders.base import Encoder
from robofailring.errors import EncoderError

Runtime = Literal["torch", "onnx", "onnx-int8", "openvino-int8"]
RUNTIMES: Final[tuple[Runtime, ...]] = ("torch", "onnx", "onnx-int8", "openvino-int8")
DEFAULT_RUNTIME: Final[Runtime] = "torch"  # a spec without `@runtime` runs its network in torch

#: What each `EncoderSpec` field a kind's arguments fill holds, as its "names no …" error says it.
FIELD_NOUNS: Final[dict[str, str]] = {"model": "model", "weights": "weights", "directory": "folder"}


def _first_word(identity: str) -> str:
    return identity.split("-")[0].lower()


def _model_of(identity: str) -> str:
    """`<model>` of an identity `<kind>:<model>:<weights>`."""
    return identity.partition(":")[2].partition(":")[0]


@dataclass(frozen=True)
class EncoderKind:
    """One encoder kind: how its spec reads and prints, what its identity is called, and its module."""

    name: str  # the spec's text before `:`, the whole spec for a kind without arguments
    module: str  # the module with `load`, `export_identity` and `network` (`Kind`), imported on first use
    help: str  # its entry in the forms `--encoder`'s help and the errors list (`specs_help`)
    # the EncoderSpec fields its `:`-separated arguments fill, in order (the first is required, the last takes
    # the rest of the text)
    fields: tuple[str, ...] = ()
    # those of its fields that may name a file or folder: made absolute by `portable` (a `directory` always, a
    # `model` or `weights` when it is a file) and stamped by `files_stamp`; the others are names, never paths
    paths: tuple[str, ...] = ()
    exports: bool = True  # it has a network a runtime (`@onnx`, …) exports
    slug: Callable[[str], str] = _first_word  # a short path-safe name of one of its identities
    # its arguments checked as the spec is read (an EncoderError), before any file is written; None: at load
    check: Callable[[EncoderSpec], None] | None = None


_KINDS: dict[str, EncoderKind] = {}


def register(kind: EncoderKind) -> EncoderKind:
    """Add an encoder kind (once per name), listed by `specs_help` in the order registered."""
    if kind.name in _KINDS:
        raise ValueError(f"encoder kind {kind.name!r} is registered already")
    _KINDS[kind.name] = kind
    return kind


def kinds() -> tuple[EncoderKind, ...]:
    """Every registered kind, in the order registered."""
    return tuple(_KINDS.values())


def kind_named(name: str) -> EncoderKind:
    """The kind called `name`; an EncoderError listing the forms when there is none."""
    kind = _KINDS.get(name)
    if kind is None:
        raise EncoderError(f"unknown encoder kind {name!r}; expected {specs_help()}")
    return kind


def identity_kind(identity: str) -> EncoderKind | None:
    """The kind an encoder identity is of: `<kind>:…`, or a name a kind without arguments begins its own with."""
    prefix = identity.partition(":")[0]
    return next(
        (
            kind
            for kind in _KINDS.values()
            if prefix == kind.name or (not kind.fields and prefix.startswith(kind.name))
        ),
        None,
    )


def _listing(names: list[str], last: str) -> str:
    return f"{', '.join(names[:-1])} {last} {names[-1]}" if len(names) > 1 else "".join(names)


def _exporting() -> list[str]:
    return [kind.name for kind in _KINDS.values() if kind.exports]


def specs_help() -> str:
    """Every registered kind's spec form, and the runtimes those with a network may end in."""
    entries = [kind.help for kind in _KINDS.values()]
    return (
        f"{', '.join(entries[:-1])}, or {entries[-1]}; an {_listing(_exporting(), 'or')} spec may end in `@onnx` "
        "or `@onnx-int8` (run through ONNX Runtime), `@openvino-int8` (static int8 on OpenVINO, the fastest on a "
        "CPU) or `@torch` (the default)"
    )


PIXELS: Final[EncoderKind] = register(
    EncoderKind("pixels", "robofailring.encoders.pixels", "`pixels` (weight-free)", exports=False)
)
OPEN_CLIP: Final[EncoderKind] = register(
    EncoderKind(
        "open_clip",
        "robofailring.encoders.openclip",
        "`open_clip:<model>[:<pretrained tag or checkpoint path>]`, e.g. `open_clip:ViT-B-32:openai` or "
        "`open_clip:ViT-L-14:/models/vit-l-14.pt`",
        fields=("model", "weights"),
        paths=("model", "weights"),  # a model-config JSON, a checkpoint
        slug=lambda identity: _model_of(identity).lower().replace("/", "-"),
    )
)
TIMM: Final[EncoderKind] = register(
    EncoderKind(
        "timm",
        "robofailring.encoders.timm_backbone",
        "`timm:<model>[:<checkpoint path>]` (a timm backbone's pooled features, e.g. "
        "`timm:efficientnet_lite0:/models/lite0.pth`)",
        fields=("model", "weights"),
        paths=("weights",),  # its model is a timm name
        slug=lambda identity: "timm-" + _model_of(identity).lower().replace("/", "-").replace(".", "-"),
    )
)
TRAINED: Final[EncoderKind] = register(
    EncoderKind(
        "trained",
        "robofailring.encoders.trained",
        "`trained:<DIR>` (a folder written by `robofailring train-encoder`)",
        fields=("directory",),
        paths=("directory",),
        # trained:<arch>:<weights digest>; two trained ones stay apart
        slug=lambda identity: f"trained-{identity.rsplit(':', 1)[-1][:8]}",
    )
)

ENCODER_SPECS_HELP: Final[str] = specs_help()


@dataclass(frozen=True)
class EncoderSpec:
    """One encoder spec: its `kind` (a registered `EncoderKind`'s name) and the fields its arguments fill."""

    kind: str
    model: str = ""  # open_clip: a model name or a model-config JSON path; timm: a model name
    weights: str = ""  # open_clip: a pretrained tag or a checkpoint path ("" for open_clip's default); timm: a checkpoint
    directory: str = ""  # trained: the folder written by `robofailring train-encoder`
    runtime: Runtime = DEFAULT_RUNTIME  # what runs the network: torch, or its ONNX export (fp32 or int8)

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
        """This spec run by `runtime` (None keeps its own); an EncoderError for an unknown runtime or for a
        kind without a network to export (`pixels`)."""
        if runtime is None or runtime == self.runtime:
            return self
        if runtime not in RUNTIMES:
            raise EncoderError(f"unknown runtime {runtime!r}; expected one of {', '.join(RUNTIMES)}")
        if not kind_named(self.kind).exports and runtime != DEFAULT_RUNTIME:
            raise EncoderError(
                f"the {self.kind} encoder has no network to run through {runtime}; runtimes apply to "
                f"{_listing(_exporting(), 'and')} encoders"
            )
        return replace(self, runtime=cast(Runtime, runtime))

    @classmethod
    def _parse_network(cls, text: str, whole: str) -> EncoderSpec:
        name, colon, rest = text.partition(":")
        kind = _KINDS.get(name)
        if kind is None or bool(colon) != bool(kind.fields):
            raise EncoderError(f"unknown encoder spec {whole!r}; expected {specs_help()}")
        values = rest.split(":", len(kind.fields) - 1) if kind.fields else []
        if kind.fields and not values[0]:
            raise EncoderError(
                f"encoder spec {whole!r} names no {FIELD_NOUNS[kind.fields[0]]}; expected {specs_help()}"
            )
        fields: dict[str, Any] = dict(zip(kind.fields, values, strict=False))
        spec = cls(name, **fields)
        if kind.check is not None:
            kind.check(spec)
        return spec

    def __str__(self) -> str:
        kind = kind_named(self.kind)
        values = [getattr(self, field) for field in kind.fields]
        while len(values) > 1 and not values[-1]:
            values.pop()
        network = ":".join([kind.name, *values])
        if not kind.exports:
            return network
        at, _, last = network.rpartition("@")
        named = at and last in RUNTIMES  # a path ending in `@onnx` needs its `@torch` said
        return network if self.runtime == DEFAULT_RUNTIME and not named else f"{network}@{self.runtime}"

    def portable(self) -> EncoderSpec:
        """The spec a memory records: a `trained:` folder or an open_clip or timm checkpoint or config file as
        an absolute path, so the memory finds its encoder again from any working directory."""
        fields: dict[str, Any] = {
            field: _portable(field, getattr(self, field)) for field in kind_named(self.kind).paths
        }
        return replace(self, **fields)

    def files_stamp(self) -> tuple[int, ...]:
        """The modification times of the files the spec names (its model, weights or every file of its folder;
        0 for a name that is no file), so a checkpoint rewritten or a folder retrained in place is seen."""
        paths = (Path(getattr(self, field)) for field in kind_named(self.kind).paths)
        named = [path for path in paths if str(path) not in ("", ".")]
        files = [f for path in named for f in (sorted(path.iterdir()) if path.is_dir() else [path])]
        return tuple(f.stat().st_mtime_ns if f.is_file() else 0 for f in files)

    @staticmethod
    def slug(identity: str) -> str:
        """A short path-safe name for an encoder identity, e.g. `vit-b-32` or `pixels`; an identity with
        a runtime (`cache.cache_identity`, `…@onnx-int8`) keeps it, e.g. `vit-b-32-onnx-int8`."""
        network, at, runtime = identity.rpartition("@")
        if at and runtime in RUNTIMES:
            return f"{EncoderSpec.slug(network)}-{runtime}"
        kind = identity_kind(identity)
        return kind.slug(identity) if kind is not None else _first_word(identity)

    @staticmethod
    def for_memory(identity: str, recorded: object) -> str:
        """The spec that reproduces a memory's encoder `identity`, given the `encoder_spec` its manifest
        recorded (None in memories older than that field)."""
        kind = identity_kind(identity)
        if kind is not None and not kind.fields:  # nothing to find: its name is its spec
            return kind.name
        if isinstance(recorded, str):
            return recorded
        if ":file-" in identity:
            name, _, rest = identity.partition(":")
            raise EncoderError(
                f"this memory was built with {identity} (a checkpoint file) and does not record where that file is; "
                f"pass --encoder {name}:{rest.partition(':')[0]}:/path/to/the/same/checkpoint"
            )
        return identity


def _portable(field: str, value: str) -> str:
    """A field's value from any working directory: a folder always absolute, a model or weights when a file."""
    if field == "directory" or Path(value).is_file():
        return str(Path(value).resolve())
    return value


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
    """What each kind's module provides (module-level functions)."""

    def load(self, spec: EncoderSpec, device: str | None) -> Encoder: ...

    def export_identity(self, spec: EncoderSpec) -> tuple[str, str]: ...

    def network(self, spec: EncoderSpec) -> Network: ...


def kind_of(spec: EncoderSpec) -> Kind:
    """The module of `spec`'s kind, imported on first use (torch only where a kind needs it)."""
    return cast(Kind, importlib.import_module(kind_named(spec.kind).module))
