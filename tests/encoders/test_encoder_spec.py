"""EncoderSpec: one parse of a spec string, its canonical, portable and slug forms, and open_encoder's memo."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from robofailring.encoders import (
    ENCODER_SPECS_HELP,
    EncoderSpec,
    encoder_slug,
    load_encoder,
    open_encoder,
    portable_spec,
)
from robofailring.errors import EncoderError


@pytest.mark.parametrize(
    ("text", "parsed"),
    [
        ("pixels", EncoderSpec("pixels")),
        (" pixels ", EncoderSpec("pixels")),
        ("open_clip:ViT-B-32:openai", EncoderSpec("open_clip", model="ViT-B-32", weights="openai")),
        ("open_clip:ViT-B-32", EncoderSpec("open_clip", model="ViT-B-32")),
        (
            "open_clip:ViT-L-14:C:/models/l.pt",
            EncoderSpec("open_clip", model="ViT-L-14", weights="C:/models/l.pt"),
        ),
        ("trained:runs/enc", EncoderSpec("trained", directory="runs/enc")),
        ("trained:runs/enc@onnx", EncoderSpec("trained", directory="runs/enc", runtime="onnx")),
        (
            "open_clip:ViT-B-32:/m/b@2.pt@onnx-int8",
            EncoderSpec("open_clip", model="ViT-B-32", weights="/m/b@2.pt", runtime="onnx-int8"),
        ),
        ("trained:runs/enc@v2", EncoderSpec("trained", directory="runs/enc@v2")),  # no runtime: a path
        ("trained:runs/enc@onnx@torch", EncoderSpec("trained", directory="runs/enc@onnx")),
    ],
)
def test_parse_and_str_round_trip(text: str, parsed: EncoderSpec) -> None:
    assert EncoderSpec.parse(text) == parsed
    assert str(parsed) == text.strip()
    assert EncoderSpec.parse(str(parsed)) == parsed
    assert EncoderSpec.parse(parsed) is parsed


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("resnet", "unknown encoder spec 'resnet'"),
        ("open_clip:", "encoder spec 'open_clip:' names no model"),
        ("trained:", "encoder spec 'trained:' names no folder"),
        ("pixels:extra", "unknown encoder spec 'pixels:extra'"),
        ("", "unknown encoder spec ''"),
    ],
)
def test_bad_specs_name_the_spec_and_list_the_forms(text: str, says: str) -> None:
    with pytest.raises(EncoderError) as caught:
        EncoderSpec.parse(text)
    assert says in str(caught.value) and ENCODER_SPECS_HELP in str(caught.value)
    with pytest.raises(EncoderError, match=says.split("'")[0]):
        load_encoder(text)


def test_portable_form_makes_files_absolute_and_leaves_names(tmp_path: Path) -> None:
    checkpoint = tmp_path / "w.pt"
    checkpoint.write_bytes(b"0")
    here = Path.cwd()
    os.chdir(tmp_path)
    try:
        assert EncoderSpec.parse("trained:enc").portable() == EncoderSpec(
            "trained", directory=str(tmp_path / "enc")
        )
        clip = EncoderSpec.parse("open_clip:ViT-B-32:w.pt").portable()
        assert clip == EncoderSpec("open_clip", model="ViT-B-32", weights=str(checkpoint))
        assert portable_spec("open_clip:ViT-B-32:w.pt") == f"open_clip:ViT-B-32:{checkpoint}"
    finally:
        os.chdir(here)
    assert EncoderSpec.parse("open_clip:ViT-B-32:openai").portable() == EncoderSpec.parse(
        "open_clip:ViT-B-32:openai"
    )
    assert str(EncoderSpec.parse(" pixels ").portable()) == "pixels"
    portable = EncoderSpec.parse(f"trained:{tmp_path}").portable()
    assert portable.portable() == portable  # idempotent


def test_slug_of_each_identity_kind() -> None:
    assert EncoderSpec.slug("pixels-v2-24px-512d") == "pixels" == encoder_slug("pixels-v2-24px-512d")
    assert EncoderSpec.slug("open_clip:ViT-B-32:openai") == "vit-b-32"
    assert EncoderSpec.slug("open_clip:hf-hub/org/Model:file-abc") == "hf-hub-org-model"
    assert EncoderSpec.slug("trained:mlp-32px-64d:0123456789abcdef") == "trained-01234567"
    assert EncoderSpec.slug(load_encoder("pixels").identity) == "pixels"


def test_spec_for_a_memory_prefers_what_it_recorded() -> None:
    assert EncoderSpec.for_memory("pixels-v2-24px-512d", None) == "pixels"
    assert EncoderSpec.for_memory("open_clip:ViT-B-32:openai", "open_clip:ViT-B-32:/abs/w.pt") == (
        "open_clip:ViT-B-32:/abs/w.pt"
    )
    assert EncoderSpec.for_memory("open_clip:ViT-B-32:openai", None) == "open_clip:ViT-B-32:openai"
    with pytest.raises(EncoderError, match="pass --encoder open_clip:ViT-B-32:/path/to/the/same/checkpoint"):
        EncoderSpec.for_memory("open_clip:ViT-B-32:file-0123", None)


def test_open_encoder_loads_each_model_once_per_spec_and_device(
    tmp_path: Path, tiny_checkpoint: tuple[Path, Path]
) -> None:
    config, checkpoint = tiny_checkpoint
    cache = tmp_path / "cache"
    first = open_encoder(f"open_clip:{config}:{checkpoint}", cache_dir=cache)
    # the same model however the spec is spelled: a parsed spec, spaces, a relative path
    here = Path.cwd()
    os.chdir(checkpoint.parent)
    try:
        relative = open_encoder(f" open_clip:{config}:{checkpoint.name} ", cache_dir=cache)
    finally:
        os.chdir(here)
    assert relative.encoder is first.encoder and relative is not first  # a fresh embedding cache handle
    parsed = EncoderSpec("open_clip", model=str(config), weights=str(checkpoint))
    assert open_encoder(parsed, cache_dir=tmp_path / "other").encoder is first.encoder
    assert open_encoder(parsed, cache_dir=tmp_path / "other").cache.path.parent == tmp_path / "other"  # type: ignore[union-attr]
    assert first.cache is not None and first.cache.path.parent == cache
    pixels = open_encoder("pixels", cache_dir=cache)
    assert (
        pixels.encoder is open_encoder(" pixels ").encoder
        and pixels.identity == load_encoder("pixels").identity
    )
    assert load_encoder("pixels") is not load_encoder("pixels")  # load_encoder itself builds a new one
    # a checkpoint rewritten in place is loaded again
    copy = tmp_path / "copy.pt"
    copy.write_bytes(checkpoint.read_bytes())
    before = open_encoder(f"open_clip:{config}:{copy}", cache_dir=cache).encoder
    assert open_encoder(f"open_clip:{config}:{copy}", cache_dir=cache).encoder is before
    os.utime(copy, ns=(1, 1))
    assert open_encoder(f"open_clip:{config}:{copy}", cache_dir=cache).encoder is not before


def test_runtimes_apply_to_networks_only() -> None:
    spec = EncoderSpec.parse("open_clip:ViT-B-32:openai")
    assert spec.runtime == "torch" and spec.with_runtime(None) is spec
    assert str(spec.with_runtime("onnx-int8")) == "open_clip:ViT-B-32:openai@onnx-int8"
    assert EncoderSpec.parse("open_clip:ViT-B-32:openai@onnx").with_runtime("torch") == spec  # --runtime wins
    with pytest.raises(EncoderError, match="unknown runtime 'tensorrt'"):
        spec.with_runtime("tensorrt")
    with pytest.raises(EncoderError, match=r"'pixels@onnx'.*no network"):
        EncoderSpec.parse("pixels@onnx")
    assert EncoderSpec.parse("pixels@torch") == EncoderSpec("pixels")
    assert EncoderSpec.slug("open_clip:ViT-B-32:file-0123@onnx-int8") == "vit-b-32-onnx-int8"
