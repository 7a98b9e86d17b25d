"""The ONNX Runtime encoders: embeddings against torch's, the export cache and its repair, the CLI option."""

from __future__ import annotations

import contextlib
import json
import logging
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from synthetic import synthetic_frame, write_project_dataset
from typer.testing import CliRunner

from robofailring import CachedEncoder, FailureMemory, load_encoder
from robofailring.cli.verbs import app
from robofailring.encoders import export as export_module
from robofailring.encoders.device import providers_for
from robofailring.encoders.export import MANIFEST_NAME, MODEL_NAME, export_folder
from robofailring.encoders.exported import OnnxEncoder
from robofailring.encoders.spec import EncoderSpec
from robofailring.encoders.training import TrainEncoderConfig, train_encoder
from robofailring.errors import EncoderError

pytestmark = pytest.mark.slow  # exports with torch: the fast lane never imports it (tests/conftest.py)

runner = CliRunner()
THRESHOLDS = {"onnx": 0.999, "onnx-int8": 0.99}  # issue 34: cosine to torch's embedding, every image


def _images(count: int = 6) -> list[np.ndarray]:
    frames = [synthetic_frame("pick_cube", "slip_wp3" if i % 2 else None, i % 3, i, 6) for i in range(count)]
    rng = np.random.default_rng(1)
    return [*frames, rng.integers(0, 256, (40, 56, 3), dtype=np.uint8)]  # and a non-square one


def _clip_spec(checkpoint: tuple[Path, Path]) -> str:
    config, weights = checkpoint
    return f"open_clip:{config}:{weights}"


@pytest.mark.parametrize("runtime", ["onnx", "onnx-int8"])
def test_open_clip_through_onnx_runtime_matches_torch(
    tiny_checkpoint: tuple[Path, Path], tmp_path: Path, runtime: str
) -> None:
    torch_encoder = load_encoder(_clip_spec(tiny_checkpoint))
    onnx_encoder = load_encoder(f"{_clip_spec(tiny_checkpoint)}@{runtime}", cache_dir=tmp_path)
    assert isinstance(onnx_encoder, OnnxEncoder) and onnx_encoder.providers == ["CPUExecutionProvider"]
    assert onnx_encoder.identity == torch_encoder.identity and onnx_encoder.dim == torch_encoder.dim
    images = _images()
    cosines = np.sum(onnx_encoder.encode(images) * torch_encoder.encode(images), axis=1)
    assert cosines.min() >= THRESHOLDS[runtime], cosines
    np.testing.assert_allclose(np.linalg.norm(onnx_encoder.encode(images), axis=1), 1.0, atol=1e-5)
    folder, _ = export_folder(EncoderSpec.parse(f"{_clip_spec(tiny_checkpoint)}@{runtime}"), tmp_path)
    assert folder.parent == tmp_path / "onnx" and (folder / MODEL_NAME).is_file()
    assert json.loads((folder / MANIFEST_NAME).read_text())["identity"] == torch_encoder.identity


def test_the_export_is_reused_on_the_second_open(
    tiny_checkpoint: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    spec = f"{_clip_spec(tiny_checkpoint)}@onnx-int8"
    first = load_encoder(spec, cache_dir=tmp_path).encode(_images())
    folders = sorted((tmp_path / "onnx").iterdir())
    assert [folder.name.split("-")[-2] for folder in folders] == ["onnx", "int8"]  # fp32, then quantized
    stamps = [(folder / MODEL_NAME).stat().st_mtime_ns for folder in folders]

    def refuse(*_: object, **__: object) -> None:
        raise AssertionError("exported again")

    monkeypatch.setattr(export_module, "export_fp32", refuse)
    monkeypatch.setattr(export_module, "quantize", refuse)
    np.testing.assert_array_equal(load_encoder(spec, cache_dir=tmp_path).encode(_images()), first)
    assert [(folder / MODEL_NAME).stat().st_mtime_ns for folder in folders] == stamps


def test_a_new_checkpoint_is_a_new_export(tiny_checkpoint: tuple[Path, Path], tmp_path: Path) -> None:
    import torch

    config, weights = tiny_checkpoint
    state = torch.load(weights, weights_only=True)
    state["state_dict"] = {key: value * 1.5 for key, value in state["state_dict"].items()}
    other = tmp_path / "other.pt"
    torch.save(state, other)
    first = load_encoder(f"{_clip_spec(tiny_checkpoint)}@onnx", cache_dir=tmp_path)
    second = load_encoder(f"open_clip:{config}:{other}@onnx", cache_dir=tmp_path)
    assert first.identity != second.identity
    assert len(list((tmp_path / "onnx").iterdir())) == 2


@pytest.mark.parametrize(
    ("damage", "said"),
    [
        ("truncate", "is incomplete or corrupt"),  # a partial copy: its size differs from export.json's
        ("scramble", "does not match the digest"),  # same size, not a model
        ("flip", "does not match the digest"),  # same size, still a model: one weight byte changed (issue 45)
        ("manifest", "is incomplete or corrupt"),  # export.json unreadable
        ("size", "preprocessing size must be 1 to 4096 px, got 100000"),  # issue 50: 1.17 TiB allocated
        ("dim", "embedding width of 10000000000"),
        # N8: an edited mean would change every embedding (and poison the embedding cache) unseen
        ("mean", "does not match the digest it records"),
        # N6/N7: a side other than the model's, even with the record re-signed: ORT's traceback, or 24 GB
        ("side", "its model takes"),
    ],
)
def test_a_broken_export_is_reported_and_made_again(
    tiny_checkpoint: tuple[Path, Path],
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    damage: str,
    said: str,
) -> None:
    spec = f"{_clip_spec(tiny_checkpoint)}@onnx"
    expected = load_encoder(spec, cache_dir=tmp_path).encode(_images())
    folder, _ = export_folder(EncoderSpec.parse(spec), tmp_path)
    model = folder / MODEL_NAME
    size = model.stat().st_size
    if damage == "truncate":
        model.write_bytes(model.read_bytes()[: size // 2])
    elif damage == "scramble":
        model.write_bytes(np.random.default_rng(0).bytes(size))
    elif damage == "flip":
        content = bytearray(model.read_bytes())
        content[-size // 3] ^= 0x01  # inside the weights, past the graph's header
        model.write_bytes(bytes(content))
    elif damage in ("size", "dim", "mean", "side"):  # export.json edited
        meta = json.loads((folder / MANIFEST_NAME).read_text())
        if damage == "size":  # re-signed: the digest is no secret, the size is checked on its own
            meta["preprocess"]["size"] = 100000
            meta["record"] = export_module._record_digest(meta)
        elif damage == "dim":
            meta["dim"] = 10**10
        elif damage == "mean":
            meta["preprocess"]["mean"] = [0.9, 0.9, 0.9]
        else:
            side = meta["preprocess"]["size"]
            meta["preprocess"]["size"] = [s + 1 for s in side] if isinstance(side, list) else side + 1
            meta["record"] = export_module._record_digest(meta)
        (folder / MANIFEST_NAME).write_text(json.dumps(meta))
    else:
        (folder / MANIFEST_NAME).write_text("{not json")
    with caplog.at_level(logging.WARNING, logger="robofailring"):
        again = load_encoder(spec, cache_dir=tmp_path)
    assert said in caplog.text and str(folder) in caplog.text and "exporting it again" in caplog.text
    np.testing.assert_allclose(again.encode(_images()), expected, atol=1e-6)
    assert model.stat().st_size == size


def test_each_runtime_has_its_own_embedding_cache(tiny_checkpoint: tuple[Path, Path], tmp_path: Path) -> None:
    paths = set()
    for runtime in ("torch", "onnx", "onnx-int8"):
        encoder = load_encoder(f"{_clip_spec(tiny_checkpoint)}@{runtime}", cache_dir=tmp_path)
        cached = CachedEncoder(encoder, cache_dir=tmp_path / "embeddings")
        assert cached.cache is not None
        paths.add(cached.cache.path)
    assert len(paths) == 3


def test_a_trained_encoder_through_onnx_runtime_matches_torch(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2, length=4)
    config = TrainEncoderConfig(
        data=data, out=tmp_path / "encoder", image_size=32, epochs=1, batch_size=32, threads=1
    )
    folder = train_encoder(config)
    torch_encoder = load_encoder(f"trained:{folder}")
    images = _images()
    reference = torch_encoder.encode(images)
    for runtime, threshold in THRESHOLDS.items():
        encoder = load_encoder(f"trained:{folder}@{runtime}", cache_dir=tmp_path / "cache")
        assert encoder.identity == torch_encoder.identity
        cosines = np.sum(encoder.encode(images) * reference, axis=1)
        assert cosines.min() >= threshold, (runtime, cosines)


def test_runtime_option_on_build_memory_and_detect(
    tiny_checkpoint: tuple[Path, Path], aha_dataset: Path, tmp_path: Path
) -> None:
    cache = ["--cache-dir", str(tmp_path / "cache")]
    spec = _clip_spec(tiny_checkpoint)
    built = runner.invoke(
        app,
        [
            "build-memory",
            str(aha_dataset),
            "--out",
            str(tmp_path / "memory"),
            "--encoder",
            spec,
            "--runtime",
            "onnx-int8",
            *cache,
        ],
    )
    assert built.exit_code == 0, built.output
    memory = FailureMemory.load(tmp_path / "memory")
    assert memory.encoder == load_encoder(spec).identity  # the torch identity: any runtime queries it
    assert sorted(folder.name.rsplit("-", 1)[0] for folder in (tmp_path / "cache" / "onnx").iterdir()) == [
        "tinyvit-test-onnx",
        "tinyvit-test-onnx-int8",
    ]
    episode = next(
        path for path in sorted(aha_dataset.rglob("*")) if path.is_dir() and "episode" in path.name
    )
    for runtime in ("onnx", "torch"):
        detected = runner.invoke(
            app,
            [
                "detect",
                str(episode),
                "--memory",
                str(tmp_path / "memory"),
                "--runtime",
                runtime,
                "--json",
                *cache,
            ],
        )
        assert detected.exit_code == 0, detected.output
    refused = runner.invoke(
        app, ["detect", str(episode), "--memory", str(tmp_path / "memory"), "--runtime", "onnx-fp16", *cache]
    )
    assert refused.exit_code != 0 and "unknown runtime 'onnx-fp16'" in refused.output


def _cached_identities(cache: Path) -> dict[str, int]:
    """The embedding caches in `cache`: each one's encoder key (`cache_identity`: the identity, `@onnx` for
    that runtime) and how many embeddings it holds."""
    held = {}
    for path in cache.glob("embeddings-*.sqlite"):
        with contextlib.closing(sqlite3.connect(path)) as db:
            (identity,) = db.execute("SELECT value FROM meta WHERE key = 'identity'").fetchone()
            (count,) = db.execute("SELECT COUNT(*) FROM emb").fetchone()
        held[identity] = count
    return held


@pytest.fixture(scope="module")
def evaluated_onnx(
    tiny_checkpoint: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory
) -> tuple[str, Path, Path, Path]:
    """(torch identity, data, memory, cache) of `evaluate --runtime onnx` with the tiny CLIP."""
    from rfr_viz.cli.app import app as full_app

    root = tmp_path_factory.mktemp("runtime-verbs")
    data = write_project_dataset(
        root / "data", tasks=("pick_cube",), symbols=("grasp_wp2", "slip_wp3"), episodes=2, length=5
    )
    spec, cache = _clip_spec(tiny_checkpoint), root / "cache"
    args = ["--encoder", spec, "--runtime", "onnx", "--target-fpr", "0.5", "--cache-dir", str(cache)]
    evaluated = runner.invoke(full_app, ["evaluate", str(data), "--out", str(root / "eval"), *args])
    assert evaluated.exit_code == 0, evaluated.output
    return load_encoder(spec).identity, data, root / "eval" / "memory", cache


def test_evaluate_encodes_through_the_runtime_it_is_given(
    evaluated_onnx: tuple[str, Path, Path, Path],
) -> None:
    identity, _, memory, cache = evaluated_onnx
    held = _cached_identities(cache)
    assert list(held) == [f"{identity}@onnx"] and held[f"{identity}@onnx"] > 0  # no torch embedding at all
    assert [folder.name.split("-")[-2] for folder in (cache / "onnx").iterdir()] == ["onnx"]
    assert FailureMemory.load(memory).encoder == identity  # any runtime queries it


@pytest.mark.parametrize("verb", ["replay", "watch"])
def test_the_recording_verbs_encode_through_the_runtime_they_are_given(
    evaluated_onnx: tuple[str, Path, Path, Path], tmp_path: Path, verb: str
) -> None:
    from rfr_viz.cli.app import app as full_app

    identity, data, memory, _ = evaluated_onnx
    episode = data / "pick_cube_slip_wp3_episode1"
    cache = tmp_path / "cache"  # its own: whatever is cached in it, this verb encoded
    out = ["--out", str(tmp_path / "rec")] if verb == "replay" else ["--save", str(tmp_path / "run.rrd")]
    args = [verb, str(episode), "--memory", str(memory), *out, "--runtime", "onnx", "--cache-dir", str(cache)]
    ran = runner.invoke(full_app, [*args, *(["--speed", "0"] if verb == "watch" else [])])
    assert ran.exit_code == 0, ran.output
    held = _cached_identities(cache)
    assert list(held) == [f"{identity}@onnx"] and held[f"{identity}@onnx"] > 0
    assert (tmp_path / "rec").is_dir() if verb == "replay" else (tmp_path / "run.rrd").is_file()


def test_cuda_without_onnxruntime_gpu_says_what_to_install() -> None:
    import onnxruntime

    if "CUDAExecutionProvider" in onnxruntime.get_available_providers():
        pytest.skip("this ONNX Runtime has CUDA")
    with pytest.raises(EncoderError, match="install onnxruntime-gpu"):
        providers_for("cuda")
    assert providers_for(None) == ["CPUExecutionProvider"]


def test_the_export_key_follows_the_model_config_and_the_calibration_frames(
    tiny_checkpoint: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An export is made from the checkpoint, the open_clip model-config file a spec names and, for the
    static int8 one, its calibration frames: another config file (same model name, other bytes) or other
    frames is another export, never the cached one of something else."""
    config, weights = tiny_checkpoint
    spec = EncoderSpec.parse(f"open_clip:{config}:{weights}@openvino-int8")
    folder, identity = export_folder(spec, tmp_path)
    (tmp_path / "other").mkdir()
    other = tmp_path / "other" / config.name
    other.write_text(json.dumps(json.loads(config.read_text()), indent=1))  # the same model, written again
    moved, same_identity = export_folder(
        EncoderSpec.parse(f"open_clip:{other}:{weights}@openvino-int8"), tmp_path
    )
    assert same_identity == identity and moved != folder
    fp32 = export_folder(spec.with_runtime("onnx"), tmp_path)[0]
    for constant, value in (("CALIBRATION_FRAMES", 16), ("CALIBRATION_SEED", 1)):
        with monkeypatch.context() as patched:
            patched.setattr(export_module, constant, value)
            assert export_folder(spec, tmp_path)[0] != folder, constant
            assert export_folder(spec.with_runtime("onnx"), tmp_path)[0] == fp32  # fp32 has no calibration


FIRST_LOAD = """
import sys, time
from pathlib import Path
from robofailring.encoders import export, load_encoder
spec, cache, me, other = sys.argv[1:]
real = export.quantize
def quantize(*args, **kwargs):
    print("quantized", flush=True)
    real(*args, **kwargs)
export.quantize = quantize
Path(cache, me).touch()
while not Path(cache, other).exists():  # both ready: the two first loads start together
    time.sleep(0.01)
load_encoder(spec, cache_dir=cache)
print("loaded", flush=True)
"""


def test_two_first_loads_at_once_make_the_export_once(
    tiny_checkpoint: tuple[Path, Path], tmp_path: Path
) -> None:
    """Issue 50: two processes loading one `onnx-int8` encoder for the first time: the second ended in
    status 1 (the export's folder busy); now it waits for the first's export and reads it."""
    import os
    import subprocess
    import sys

    spec = f"{_clip_spec(tiny_checkpoint)}@onnx-int8"
    started = [
        subprocess.Popen(
            [sys.executable, "-c", FIRST_LOAD, spec, str(tmp_path), me, other],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "ROBOFAILRING_PROGRESS": "0"},
        )
        for me, other in (("a", "b"), ("b", "a"))
    ]
    outputs = [process.communicate(timeout=600) for process in started]
    assert [process.returncode for process in started] == [0, 0], outputs
    said = [stdout.split() for stdout, _ in outputs]
    assert sorted(word for words in said for word in words) == ["loaded", "loaded", "quantized"]
    assert sorted(folder.name.split("-")[-2] for folder in (tmp_path / "onnx").iterdir()) == ["int8", "onnx"]
    assert not [path.name for path in (tmp_path / "onnx").iterdir() if path.name.startswith(".")]
