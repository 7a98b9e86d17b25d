"""Encoders: the weight-free one, the real open_clip loading path, and the embedding cache."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from synthetic import synthetic_frame, write_project_dataset

from robofailring import CachedEncoder, FailureMemory, Frame, load_encoder
from robofailring.encoders.pixels import PixelEncoder
from robofailring.errors import EncoderError


def _images(count: int) -> list[np.ndarray]:
    return [
        synthetic_frame("pick_cube", "slip_wp3" if i % 2 else None, i % 3, i, count) for i in range(count)
    ]


def test_pixel_encoder_is_unit_norm_512_and_deterministic() -> None:
    images = _images(4)
    first, second = PixelEncoder().encode(images), PixelEncoder().encode(images)
    assert first.shape == (4, 512) and first.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(first, axis=1), 1.0, atol=1e-5)
    np.testing.assert_array_equal(first, second)
    assert load_encoder("pixels").identity == PixelEncoder().identity
    # identical images -> similarity 1; different scenes -> clearly lower
    assert float(first[0] @ PixelEncoder().encode([images[0]])[0]) == pytest.approx(1.0, abs=1e-5)
    assert float(first[0] @ first[1]) < 0.95


def test_open_clip_checkpoint_loads_through_the_user_path(tiny_checkpoint: tuple[Path, Path]) -> None:
    import open_clip
    import torch

    config, checkpoint = tiny_checkpoint
    encoder = load_encoder(f"open_clip:{config}:{checkpoint}")
    assert encoder.dim == 16
    assert encoder.identity.startswith("open_clip:TinyViT-test:file-")
    images = _images(5)
    embeddings = encoder.encode(images)
    assert embeddings.shape == (5, 16) and embeddings.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(embeddings, axis=1), 1.0, atol=1e-5)
    # the same weights used directly through open_clip give the same embeddings
    model, _, preprocess = open_clip.create_model_and_transforms("TinyViT-test", pretrained=str(checkpoint))
    model.eval()
    from PIL import Image

    with torch.inference_mode():
        direct = model.encode_image(torch.stack([preprocess(Image.fromarray(i)) for i in images])).numpy()
    direct /= np.linalg.norm(direct, axis=1, keepdims=True)
    np.testing.assert_allclose(embeddings, direct, atol=1e-5)
    # a different checkpoint is a different identity
    assert load_encoder(f"open_clip:{config}:{checkpoint}").identity == encoder.identity


def test_open_clip_errors_say_how_to_provide_weights(
    tiny_checkpoint: tuple[Path, Path], tmp_path: Path
) -> None:
    config, _ = tiny_checkpoint
    with pytest.raises(EncoderError, match="needs weights"):
        load_encoder("open_clip:ViT-B-32")
    with pytest.raises(EncoderError, match=r"missing\.pt does not exist"):
        load_encoder(f"open_clip:ViT-B-32:{tmp_path / 'missing.pt'}")
    with pytest.raises(EncoderError, match="neither a checkpoint file nor a pretrained tag"):
        load_encoder("open_clip:ViT-B-32:no-such-tag")
    with pytest.raises(EncoderError, match="unknown open_clip model"):
        load_encoder("open_clip:ViT-Q-99:openai")
    with pytest.raises(EncoderError, match="unknown encoder spec"):
        load_encoder("resnet")
    wrong = tmp_path / "wrong.pt"
    wrong.write_bytes(b"garbage")
    with pytest.raises(EncoderError, match="cannot load checkpoint"):
        load_encoder(f"open_clip:{config}:{wrong}")


class CountingEncoder:
    """Wraps an encoder and counts the images it is asked to encode."""

    def __init__(self) -> None:
        self.inner = PixelEncoder()
        self.encoded = 0

    @property
    def identity(self) -> str:
        return self.inner.identity

    @property
    def dim(self) -> int:
        return self.inner.dim

    def encode(self, images: Sequence[np.ndarray]) -> np.ndarray:
        self.encoded += len(images)
        return self.inner.encode(images)


def test_cache_second_pass_encodes_nothing(tmp_path: Path, cache_dir: Path) -> None:
    from robofailring.data.images import write_png

    paths = []
    for i, image in enumerate(_images(6)):
        write_png(tmp_path / f"{i}.png", image)
        paths.append(tmp_path / f"{i}.png")
    frames = [Frame(path=p) for p in paths]
    counting = CountingEncoder()
    first = CachedEncoder(counting, cache_dir=cache_dir).encode_frames(frames)
    assert counting.encoded == 6
    again = CachedEncoder(counting, cache_dir=cache_dir)  # a new process would open the same file
    second = again.encode_frames(frames + frames[:2])
    assert counting.encoded == 6 and again.hits == 8
    np.testing.assert_array_equal(second[:6], first)
    # content, not path, is the key: a copy of an image hits the cache
    (tmp_path / "copy.png").write_bytes(paths[0].read_bytes())
    again.encode_frames([Frame(path=tmp_path / "copy.png")])
    assert counting.encoded == 6


@pytest.mark.slow  # imports open_clip and torch: the fast lane never does (tests/conftest.py)
def test_pretrained_tag_without_network_fails_fast_with_instructions() -> None:
    with pytest.raises(EncoderError, match="not available here") as error:
        load_encoder("open_clip:ViT-B-32:openai")
    assert "open_clip:ViT-B-32:/path/to/checkpoint.pt" in str(error.value)
    assert error.value.exit_code == 1  # the environment lacks them (issue 35, item 9): not bad input


def test_cache_notices_a_rewritten_file(tmp_path: Path, cache_dir: Path) -> None:
    from robofailring.data.images import write_png

    path = tmp_path / "frame.png"
    images = _images(2)
    write_png(path, images[0])
    counting = CountingEncoder()
    first = CachedEncoder(counting, cache_dir=cache_dir).encode_frames([Frame(path=path)])
    write_png(path, images[1])
    import os

    os.utime(path, ns=(1, 1))  # a different mtime, as any real rewrite has
    second = CachedEncoder(counting, cache_dir=cache_dir).encode_frames([Frame(path=path)])
    assert counting.encoded == 2
    np.testing.assert_array_equal(second[0], PixelEncoder().encode([images[1]])[0])
    assert not np.array_equal(first, second)


def test_memories_record_encoder_files_as_absolute_paths(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, tiny_checkpoint: tuple[Path, Path]
) -> None:
    """A relative `trained:` folder or checkpoint path would not resolve from another working directory."""
    from robofailring.encoders import portable_spec

    config, checkpoint = tiny_checkpoint
    monkeypatch.chdir(checkpoint.parent)
    assert (
        portable_spec(f"trained:{tmp_path.name}")
        == f"trained:{(checkpoint.parent / tmp_path.name).resolve()}"
    )
    assert (
        portable_spec(f"open_clip:{config.name}:{checkpoint.name}")
        == f"open_clip:{config.resolve()}:{checkpoint.resolve()}"
    )
    assert portable_spec("open_clip:ViT-B-32:openai") == "open_clip:ViT-B-32:openai"
    assert portable_spec(" pixels ") == "pixels"


def test_an_open_clip_model_with_a_timm_tower_goes_through_every_verb(
    tiny_timm_checkpoint: tuple[Path, Path], tmp_path: Path
) -> None:
    """Issue 46 item 1: SigLIP and the ConvNeXt CLIPs have a timm image tower, which has no `output_dim`:
    loading one ended in an AttributeError traceback. Its width now comes from the model's config."""
    from typer.testing import CliRunner

    from rfr_viz.cli.app import app

    config, checkpoint = tiny_timm_checkpoint
    encoder = load_encoder(f"open_clip:{config}:{checkpoint}")
    assert encoder.dim == 16 and encoder.encode(_images(3)).shape == (3, 16)
    data = write_project_dataset(
        tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=4, length=4
    )
    spec, cache = f"open_clip:{config}:{checkpoint}", ["--cache-dir", str(tmp_path / "cache")]
    memory, runner = tmp_path / "memory", CliRunner()
    for arguments in (
        ["build-memory", str(data), "--out", str(memory), "--encoder", spec, "--split", "train"],
        ["calibrate", str(data), "--memory", str(memory), "--target-fpr", "0.5"],
        ["detect", str(data), "--memory", str(memory), "--trajectory", "pick_cube_grasp_wp2_episode1", "--json"],
        ["replay", str(data), "--memory", str(memory), "--trajectory", "pick_cube_grasp_wp2_episode1",
         "--out", str(tmp_path / "recordings")],
    ):  # fmt: skip
        result = runner.invoke(app, [*arguments, *cache])
        assert result.exit_code == 0, result.output
        if arguments[0] == "detect":
            assert json.loads(result.stdout)["encoder"] == encoder.identity
    assert len(list((tmp_path / "recordings").glob("*.rrd"))) == 1
    assert FailureMemory.load(memory).dim == 32  # the pair of two 16-d embeddings
