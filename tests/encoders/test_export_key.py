"""What an export's cache key covers (robofailring.encoders.export): everything the export is made from, so a
change to any of it is a new export rather than an old one reused (docs/runtime.md)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robofailring.encoders import export as export_module
from robofailring.encoders.export import export_folder, spec_identity
from robofailring.encoders.spec import EncoderSpec

TIMM = "timm:efficientnet_lite0"  # its identity needs no weights nor torch: the key is found without loading


def test_the_int8_calibration_frames_are_part_of_the_openvino_key(monkeypatch: pytest.MonkeyPatch) -> None:
    """openvino-int8 is calibrated on `calibration_images()`: their count and seed are in its key, so other
    calibration frames make a new export; the other runtimes use none and keep theirs."""
    spec = EncoderSpec.parse(f"{TIMM}@openvino-int8")
    identity, key = spec_identity(spec)
    others = {
        runtime: spec_identity(EncoderSpec.parse(f"{TIMM}@{runtime}"))[1] for runtime in ("onnx", "onnx-int8")
    }
    for name, value in (("CALIBRATION_FRAMES", 64), ("CALIBRATION_SEED", 1)):
        with monkeypatch.context() as patched:
            patched.setattr(export_module, name, value)
            assert spec_identity(spec) != (identity, key) and spec_identity(spec)[0] == identity, name
            changed = {
                runtime: spec_identity(EncoderSpec.parse(f"{TIMM}@{runtime}"))[1] for runtime in others
            }
            assert changed == others, name
    assert spec_identity(spec) == (identity, key)


@pytest.mark.slow  # the spec is checked by open_clip, which imports torch
def test_the_open_clip_model_config_is_part_of_the_key(tmp_path: Path) -> None:
    """`open_clip:<config.json>:<checkpoint>`: the same file names and checkpoint with another config in the
    file is another network, so another export (the identity, which names the model and weights, is the same)."""
    weights = tmp_path / "weights.pt"
    weights.write_bytes(b"the same checkpoint file")
    keys = []
    for width in (32, 64):
        config = tmp_path / f"width{width}" / "KeyTest-tiny.json"
        config.parent.mkdir()
        config.write_text(
            json.dumps(
                {
                    "embed_dim": 16,
                    "vision_cfg": {
                        "image_size": 32,
                        "layers": 1,
                        "width": width,
                        "head_width": 16,
                        "patch_size": 8,
                    },
                    "text_cfg": {"context_length": 8, "vocab_size": 64, "width": 16, "heads": 1, "layers": 1},
                }
            )
        )
        keys.append(
            export_folder(EncoderSpec.parse(f"open_clip:{config}:{weights}@onnx"), tmp_path / "cache")
        )
    (first, first_identity), (second, second_identity) = keys
    assert first_identity == second_identity and first != second
