"""Encoder kinds, each registered once (`encoders/spec.py`, issue 53): every kind's spec forms, identities and
slugs as they always were, a kind registered alone read, printed, listed and loaded like the others, and no
kind module imported until an encoder of it is loaded."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import robofailring.encoders.spec as spec_module
from robofailring.cli.verbs import app
from robofailring.encoders import ENCODER_SPECS_HELP, EncoderSpec, load_encoder
from robofailring.encoders.base import file_digest
from robofailring.encoders.spec import EncoderKind, Network, kind_of, kinds, register, specs_help
from robofailring.errors import EncoderError

#: `--encoder`'s forms, word for word as the CLI has always printed them (docs/cli.md).
FORMS = (
    "`pixels` (weight-free), `open_clip:<model>[:<pretrained tag or checkpoint path>]`, e.g. "
    "`open_clip:ViT-B-32:openai` or `open_clip:ViT-L-14:/models/vit-l-14.pt`, `timm:<model>[:<checkpoint path>]` "
    "(a timm backbone's pooled features, e.g. `timm:efficientnet_lite0:/models/lite0.pth`), or `trained:<DIR>` "
    "(a folder written by `robofailring train-encoder`); an open_clip, timm or trained spec may end in `@onnx` or "
    "`@onnx-int8` (run through ONNX Runtime), `@openvino-int8` (static int8 on OpenVINO, the fastest on a CPU) or "
    "`@torch` (the default)"
)

# spec text → (str, portable with the working directory as <cwd>), for each kind's forms
SAMPLES = {
    "pixels": ("pixels", "pixels"),
    " pixels@torch ": ("pixels", "pixels"),
    "open_clip:ViT-B-32:openai": ("open_clip:ViT-B-32:openai", "open_clip:ViT-B-32:openai"),
    "open_clip:ViT-B-32": ("open_clip:ViT-B-32", "open_clip:ViT-B-32"),
    "open_clip:cfg.json:w.pt@onnx": (
        "open_clip:cfg.json:w.pt@onnx",
        "open_clip:<cwd>/cfg.json:<cwd>/w.pt@onnx",
    ),
    "open_clip:ViT-L-14:C:/models/l.pt": (
        "open_clip:ViT-L-14:C:/models/l.pt",
        "open_clip:ViT-L-14:C:/models/l.pt",
    ),
    "timm:efficientnet_lite0": ("timm:efficientnet_lite0", "timm:efficientnet_lite0"),
    "timm:efficientnet_lite0:w.pt@openvino-int8": (
        "timm:efficientnet_lite0:w.pt@openvino-int8",
        "timm:efficientnet_lite0:<cwd>/w.pt@openvino-int8",
    ),
    "timm:hf-hub/org/Model.v2:w.pt@onnx@torch": (
        "timm:hf-hub/org/Model.v2:w.pt@onnx@torch",
        "timm:hf-hub/org/Model.v2:w.pt@onnx@torch",
    ),
    "timm:m:a:b": ("timm:m:a:b", "timm:m:a:b"),
    "trained:enc": ("trained:enc", "trained:<cwd>/enc"),
    "trained:runs/enc@v2": ("trained:runs/enc@v2", "trained:<cwd>/runs/enc@v2"),
    "trained:runs/enc@onnx@torch": ("trained:runs/enc@onnx@torch", "trained:<cwd>/runs/enc@onnx@torch"),
}

SLUGS = {
    "pixels-v2-24px-512d": "pixels",
    "pixels-v2-24px-512d@onnx": "pixels-onnx",
    "open_clip:ViT-B-32:openai": "vit-b-32",
    "open_clip:hf-hub/org/Model:file-abc": "hf-hub-org-model",
    "open_clip:ViT-B-32:file-0123@onnx-int8": "vit-b-32-onnx-int8",
    "timm:efficientnet_lite0:pretrained": "timm-efficientnet_lite0",
    "timm:hf-hub/Org/Model.v2:file-0123": "timm-hf-hub-org-model-v2",
    "timm:m:file-1@openvino-int8": "timm-m-openvino-int8",
    "trained:cnn4-32px-64d:0123456789abcdef": "trained-01234567",
    "weird-thing:x": "weird",
}


def test_every_kind_reads_prints_and_travels_as_it_always_did(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "w.pt").write_bytes(b"0")
    (tmp_path / "cfg.json").write_text("{}")
    monkeypatch.chdir(tmp_path)
    assert ENCODER_SPECS_HELP == specs_help() == FORMS
    assert [kind.name for kind in kinds()] == ["pixels", "open_clip", "timm", "trained"]
    for text, (printed, portable) in SAMPLES.items():
        parsed = EncoderSpec.parse(text)
        assert (str(parsed), str(parsed.portable()).replace(str(tmp_path), "<cwd>")) == (printed, portable), (
            text
        )
        assert EncoderSpec.parse(str(parsed)) == parsed
    assert {identity: EncoderSpec.slug(identity) for identity in SLUGS} == SLUGS
    with pytest.raises(EncoderError) as caught:
        EncoderSpec.parse("pixels@onnx")
    assert str(caught.value) == (
        "encoder spec 'pixels@onnx': the pixels encoder has no network to run through onnx; runtimes apply to "
        "open_clip, timm and trained encoders"
    )


def test_identities_and_the_spec_a_memory_is_opened_with(tmp_path: Path) -> None:
    checkpoint = tmp_path / "w.pth"
    checkpoint.write_bytes(b"weights")
    timm = EncoderSpec.parse(f"timm:efficientnet_lite0:{checkpoint}")
    identity = f"timm:efficientnet_lite0:file-{file_digest(checkpoint)}"
    assert kind_of(timm).export_identity(timm) == (identity, identity)  # found without torch
    assert load_encoder("pixels").identity == "pixels-v2-24px-512d"
    assert EncoderSpec.for_memory("pixels-v2-24px-512d", None) == "pixels"
    assert EncoderSpec.for_memory("open_clip:ViT-B-32:openai", None) == "open_clip:ViT-B-32:openai"
    assert EncoderSpec.for_memory(identity, str(timm)) == str(timm)
    # a memory older than its recorded spec names the kind it was built with (it said open_clip: for timm)
    with pytest.raises(
        EncoderError, match="pass --encoder timm:efficientnet_lite0:/path/to/the/same/checkpoint"
    ):
        EncoderSpec.for_memory(identity, None)


class _Flat:
    """The `flat` test kind's encoder: every frame's mean colour, made unit."""

    identity = "flat-v1"
    dim = 3

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        means = np.array([image.reshape(-1, 3).mean(axis=0) for image in images], dtype=np.float32)
        return means / np.linalg.norm(means, axis=1, keepdims=True)


def load(spec: EncoderSpec, device: str | None) -> _Flat:
    return _Flat()


def export_identity(spec: EncoderSpec) -> tuple[str, str]:
    raise EncoderError("flat has no network")


def network(spec: EncoderSpec) -> Network:
    raise EncoderError("flat has no network")


@pytest.fixture
def flat_kind(monkeypatch: pytest.MonkeyPatch) -> EncoderKind:
    """A kind registered alone, as a new kind's module registers it: this module is its module."""
    monkeypatch.setattr(spec_module, "_KINDS", dict(spec_module._KINDS))
    return register(
        EncoderKind(
            "flat", __name__, "`flat:<name>` (a test kind)", fields=("model",), exports=False, check=_named
        )
    )


def _named(spec: EncoderSpec) -> None:
    if not spec.model.isalpha():
        raise EncoderError(f"a flat encoder is named in letters, got {spec.model!r}")


def test_a_kind_registered_alone_is_read_printed_listed_and_loaded(
    flat_kind: EncoderKind, tmp_path: Path
) -> None:
    (tmp_path / "data").mkdir()
    parsed = EncoderSpec.parse("flat:grey")
    assert parsed == EncoderSpec("flat", model="grey") and str(parsed) == "flat:grey"
    assert EncoderSpec.slug("flat-v1") == "flat" and EncoderSpec.for_memory("flat-v1", None) == "flat-v1"
    encoder = load_encoder("flat:grey")
    assert isinstance(encoder, _Flat)
    assert encoder.encode([np.full((4, 4, 3), 7, np.uint8)]).tolist() == [[pytest.approx(3**-0.5)] * 3]
    assert "`flat:<name>` (a test kind); an open_clip, timm or trained spec" in specs_help()
    with pytest.raises(EncoderError, match=r"names no model; expected .*`flat:<name>`"):
        EncoderSpec.parse("flat:")
    with pytest.raises(EncoderError, match="the flat encoder has no network to run through onnx"):
        EncoderSpec.parse("flat:grey@onnx")
    with pytest.raises(ValueError, match="registered already"):
        register(flat_kind)
    with pytest.raises(EncoderError, match="named in letters, got '8'"):  # its own check, as the spec is read
        EncoderSpec.parse("flat:8")

    # the CLI's error lists the forms the registry holds
    result = CliRunner().invoke(
        app, ["build-memory", str(tmp_path / "data"), "--out", str(tmp_path / "m"), "--encoder", "vgg"]
    )
    assert result.exit_code == 2 and "unknown encoder spec 'vgg'" in result.output
    assert "`flat:<name>` (a test kind)" in " ".join(result.output.split())


def test_a_name_is_never_taken_for_a_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Only a kind's path fields are made absolute and stamped: a timm model named like a file in the working
    folder stays a timm name (before, `timm:resnet50` became `timm:/…/resnet50` in the memory's manifest)."""
    monkeypatch.chdir(tmp_path)
    for name in ("resnet50", "w.pth", "cfg.json"):
        (tmp_path / name).write_text("x")
    timm = EncoderSpec.parse("timm:resnet50:w.pth").portable()
    assert (timm.model, timm.weights) == ("resnet50", str(tmp_path / "w.pth"))
    assert len(EncoderSpec.parse("timm:resnet50:w.pth").files_stamp()) == 1  # the checkpoint alone
    clip = EncoderSpec.parse("open_clip:cfg.json:w.pth").portable()  # open_clip's model may be a config file
    assert (clip.model, clip.weights) == (str(tmp_path / "cfg.json"), str(tmp_path / "w.pth"))


#: Every spec form read, printed, made portable and slugged in a fresh interpreter: which modules that imports.
LIGHT = """
import json, sys
from robofailring.encoders import ENCODER_SPECS_HELP, EncoderSpec
for text in ("pixels", "open_clip:ViT-B-32:openai@onnx", "timm:m:w.pth@openvino-int8", "trained:enc@onnx-int8"):
    spec = EncoderSpec.parse(text)
    str(spec), spec.portable(), spec.files_stamp(), EncoderSpec.slug(text)
heavy = {"torch", "open_clip", "timm", "onnxruntime", "openvino"}
kinds = {"pixels", "openclip", "timm_backbone", "trained"}
print(json.dumps(sorted(
    name for name in sys.modules
    if name.split(".")[0] in heavy or name.removeprefix("robofailring.encoders.") in kinds
)))
"""


def test_reading_specs_imports_no_kind_module(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-c", LIGHT],
        capture_output=True,
        text=True,
        check=True,
        cwd=tmp_path,
        env=dict(os.environ),
    )
    assert json.loads(done.stdout) == []
