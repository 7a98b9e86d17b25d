"""An encoder's network exported to ONNX once, and quantized to int8, cached by what it was made from.

An export is a folder `<cache dir>/onnx/<slug>-<runtime>-<key>/` (the cache dir of `default_cache_dir`,
or `--cache-dir`) holding `model.onnx` and `export.json`. The key digests the encoder identity (which
names the checkpoint's or trained folder's weights digest), the model-config file when the spec names
one, the runtime and `EXPORT_VERSION`, so a new checkpoint is a new export and an unchanged one is
never exported twice. The folder is written whole under a temporary name and renamed into place
(`atomic_directory`); `export.json` records each file's size and digest, and the digest of what it says
(identity, width, runtime, preprocessing) with the model's; a folder whose files or record do not match
them, whose preprocessing size is not the model's input side, or that ONNX Runtime cannot read, is
reported and exported again.

The exported graph maps normalised pixels, (N, 3, S, S) float32, to the unnormalised embedding, as
torch computes it; the preprocessing (open_clip's own transform, or the trained encoder's square
resize and normalisation) is recorded in `export.json` and run outside the graph (`exported.py`).
`onnx-int8` is that graph quantized dynamically for ONNX Runtime, `openvino-int8` statically (int8
weights and activations, symmetric) for OpenVINO (`quantize.py`; bench/bench_runtime.py measures each).
"""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from robofailring.atomic import atomic_directory, output_lock
from robofailring.bounded import read_regular
from robofailring.encoders.base import file_digest
from robofailring.encoders.cache import default_cache_dir
from robofailring.encoders.preprocess import Preprocess, check_preprocess
from robofailring.encoders.quantize import (
    CALIBRATION_FRAMES,
    CALIBRATION_SEED,
    STATIC_SCHEME,
    calibration_images,
    quantize,
)
from robofailring.encoders.spec import EncoderSpec, kind_of
from robofailring.errors import EncoderError
from robofailring.extras import needs_extra
from robofailring.jsontext import parse_json

EXPORT_VERSION: Final[int] = 1
MODEL_NAME: Final[str] = "model.onnx"
MANIFEST_NAME: Final[str] = "export.json"
OPSET: Final[int] = 17
MANIFEST_LIMIT: Final[int] = 1 << 20  # export.json: a few hundred bytes
MAX_DIM: Final[int] = 1 << 16  # an embedding's width (ViT-bigG: 1,280)

_log = logging.getLogger("robofailring")


@dataclass(frozen=True)
class Export:
    """A complete export folder: its ONNX file and what `export.json` says about it."""

    folder: Path
    identity: str  # the encoder identity, the same as the torch encoder's
    dim: int
    runtime: str  # onnx (fp32), onnx-int8 or openvino-int8
    preprocess: dict[
        str, Any
    ]  # {"kind": "open_clip", ...open_clip's PreprocessCfg} or {"kind": "square", ...}

    @property
    def model(self) -> Path:
        return self.folder / MODEL_NAME


MadeFrom = tuple[str, str]  # a kind's `export_identity`: the identity and what an export is made from


def spec_identity(spec: EncoderSpec, made_from: MadeFrom | None = None) -> tuple[str, str]:
    """(the encoder identity, the export key) of a spec, found without loading its network (`made_from`:
    the kind's answer when the caller has it already, so a checkpoint is digested once per export)."""
    identity, material = made_from or kind_of(spec).export_identity(spec)
    if (
        spec.runtime == "openvino-int8"
    ):  # its calibration frames and static form are part of what it is made from
        material += f"|calibration-{CALIBRATION_FRAMES}-{CALIBRATION_SEED}|{STATIC_SCHEME}"
    key = hashlib.blake2b(f"{material}|{spec.runtime}|v{EXPORT_VERSION}".encode(), digest_size=8).hexdigest()
    return identity, key


def export_folder(
    spec: EncoderSpec, cache_dir: Path | None = None, made_from: MadeFrom | None = None
) -> tuple[Path, str]:
    """Where the export of `spec` (with its runtime) lives, and the encoder identity."""
    identity, key = spec_identity(spec, made_from)
    root = (Path(cache_dir) if cache_dir is not None else default_cache_dir()) / "onnx"
    return root / f"{EncoderSpec.slug(identity)}-{spec.runtime}-{key}", identity


def read_export(folder: Path) -> Export | None:
    """The export in `folder`, None when there is none; an EncoderError when it is incomplete or corrupt."""
    if not folder.exists():
        return None
    manifest = folder / MANIFEST_NAME
    try:
        text = read_regular(manifest, limit=MANIFEST_LIMIT, error=EncoderError)
        meta = parse_json(text, source=str(manifest), error=EncoderError)
        files = meta["files"]
        for name, recorded in files.items():
            if not isinstance(recorded, dict):
                raise EncoderError(
                    f"{MANIFEST_NAME} records no digest of {name} (an earlier version's export)"
                )
            found = (folder / name).stat().st_size
            if found != recorded["bytes"]:
                raise EncoderError(f"{name} has {found} bytes, {MANIFEST_NAME} says {recorded['bytes']}")
            if file_digest(folder / name) != recorded["blake2b"]:
                raise EncoderError(
                    f"{name} does not match the digest {MANIFEST_NAME} records (changed since)"
                )
        dim = meta["dim"]
        if type(dim) is not int or not 1 <= dim <= MAX_DIM:
            raise EncoderError(f"{MANIFEST_NAME} gives an embedding width of {dim!r}, not 1 to {MAX_DIM}")
        if meta.get("record") != _record_digest(meta):
            raise EncoderError(
                f"{MANIFEST_NAME}'s identity, width, runtime or preprocessing does not match the digest it "
                "records with the model's (changed since, or an earlier version's export)"
            )
        preprocess = check_preprocess(meta["preprocess"])  # what the digest covers, checked before it sizes
        return Export(folder, str(meta["identity"]), dim, str(meta["runtime"]), preprocess)
    except (OSError, ValueError, KeyError, TypeError, AttributeError, EncoderError) as error:
        raise EncoderError(f"the cached ONNX export {folder} is incomplete or corrupt ({error})") from error


def _write(folder: Path, identity: str, dim: int, runtime: str, preprocess: dict[str, Any]) -> Export:
    """Record `export.json` beside the model file already written in `folder` (a temporary folder)."""
    meta = {
        "format": "robofailring-onnx-export",
        "version": EXPORT_VERSION,
        "identity": identity,
        "dim": dim,
        "runtime": runtime,
        "preprocess": preprocess,
        "files": {
            MODEL_NAME: {
                "bytes": (folder / MODEL_NAME).stat().st_size,
                "blake2b": file_digest(
                    folder / MODEL_NAME
                ),  # a corrupted file of the same size is made again
            }
        },
    }
    meta["record"] = _record_digest(meta)
    (folder / MANIFEST_NAME).write_text(json.dumps(meta, indent=2), encoding="utf-8")
    return Export(folder, identity, dim, runtime, preprocess)


def _record_digest(meta: dict[str, Any]) -> str:
    """The digest of what `export.json` says about the model (its preprocessing too: a changed mean, std or
    size would change every embedding) together with the model file's own digest."""
    recorded = {field: meta[field] for field in ("identity", "dim", "runtime", "preprocess", "files")}
    return hashlib.blake2b(json.dumps(recorded, sort_keys=True).encode(), digest_size=8).hexdigest()


def export_fp32(spec: EncoderSpec, folder: Path) -> Export:
    """Export the torch network of `spec` into the (temporary) `folder` as fp32 ONNX."""
    with needs_extra("onnx"):
        import onnx  # noqa: F401  (torch's exporter writes through it)
    with needs_extra("clip"):
        import torch

    network = kind_of(spec).network(spec)
    example = torch.zeros(2, 3, network.side, network.side)
    try:  # not under inference_mode: torch's fused attention kernel has no ONNX form
        with warnings.catch_warnings():  # the tracer's notes on shape checks, for torch developers
            warnings.simplefilter("ignore")
            torch.onnx.export(
                network.module,
                (example,),
                str(folder / MODEL_NAME),
                input_names=["pixels"],
                output_names=["embedding"],
                dynamic_axes={"pixels": {0: "batch"}, "embedding": {0: "batch"}},
                opset_version=OPSET,
                dynamo=False,  # the TorchScript exporter: no onnxscript needed
            )
    except Exception as error:  # torch's exporter raises many types for an unsupported graph
        raise EncoderError(
            f"cannot export {network.identity} to ONNX: {type(error).__name__}: {error}"
        ) from error
    return _write(folder, network.identity, network.dim, "onnx", network.preprocess)


def ensure_export(
    spec: EncoderSpec, cache_dir: Path | None = None, made_from: MadeFrom | None = None
) -> Export:
    """The cached export of `spec` for its runtime (`onnx`, `onnx-int8`, `openvino-int8`), made once when
    absent (an int8 one from the fp32 one, made first); an incomplete or corrupt one is reported and made again.
    A second process asking for an export the first is making waits for it, then reads it."""
    made_from = made_from or kind_of(spec).export_identity(spec)
    folder, identity = export_folder(spec, cache_dir, made_from)
    found = _cached(folder)
    if found is not None:
        return found
    with output_lock(folder, wait=True):
        found = _cached(folder)  # made by another process while this one waited
        if found is not None:
            return found
        _make(spec, folder, identity, cache_dir, made_from)
    made = read_export(folder)
    assert made is not None
    return made


def _cached(folder: Path) -> Export | None:
    """The complete export in `folder`, or None (a broken one reported and removed)."""
    try:
        return read_export(folder)
    except EncoderError as error:
        _log.warning("warning: %s; exporting it again", error)
        discard_export(folder)
        return None


def _make(
    spec: EncoderSpec, folder: Path, identity: str, cache_dir: Path | None, made_from: MadeFrom
) -> None:
    """Export (or quantize) `spec` into `folder`, holding its lock."""
    if spec.runtime == "onnx":
        _log.info("exporting %s to ONNX (once; cached in %s)", identity, folder)
        with atomic_directory(folder) as tmp:
            export_fp32(spec, tmp)
    elif spec.runtime in ("onnx-int8", "openvino-int8"):
        fp32 = ensure_export(spec.with_runtime("onnx"), cache_dir, made_from)
        static = spec.runtime == "openvino-int8"  # static for OpenVINO, dynamic for ONNX Runtime
        pixels = Preprocess(fp32.preprocess)(calibration_images()) if static else None
        _log.info("quantizing %s to int8 for %s (once; cached in %s)", identity, spec.runtime, folder)
        with atomic_directory(folder) as tmp:
            quantize(fp32.model, tmp / MODEL_NAME, mode="static" if static else "dynamic", calibration=pixels)
            _write(tmp, fp32.identity, fp32.dim, spec.runtime, fp32.preprocess)
    else:
        raise EncoderError(f"runtime {spec.runtime} has no ONNX export")


def discard_export(folder: Path) -> None:
    """Remove a broken export folder, so that it is made again (under its lock: never one being made)."""
    with output_lock(folder, wait=True):
        shutil.rmtree(folder, ignore_errors=True)
