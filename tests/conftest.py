"""Shared fixtures: tiny synthetic datasets written as real PNG files, and the pixels memory built from one."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest

# One OpenMP/BLAS thread per test process, set before numpy or faiss loads (xdist workers and the
# subprocesses tests start inherit it): the fast lane runs one worker per core, and faiss's OpenMP
# threads spin-waiting against the other worker's made the small searches several times slower.
for _threads in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

pytest.register_assert_rewrite("fault_helpers")  # the fault tests' shared checks

import functools  # noqa: E402

import numpy as np  # noqa: E402
import typer.testing  # noqa: E402
from hypothesis import settings  # noqa: E402
from synthetic import write_aha_dataset  # noqa: E402

from robofailring import CachedEncoder, FailureMemory, load_dataset, load_encoder  # noqa: E402
from robofailring.data.model import Frame  # noqa: E402

# Property tests (tests/**/test_*_properties.py): fast, and no example database written into the repo.
settings.register_profile("robofailring", max_examples=25, deadline=None, database=None)
settings.load_profile("robofailring")

# typer's CliRunner rebuilds the click command from every verb's signature on each invoke (~50 ms, some
# 400 times a run); an app does not change during the tests, so each is built once and invoked as built.
typer.testing._get_command = functools.cache(typer.testing._get_command)  # type: ignore[attr-defined]

TORCH_FIXTURES = frozenset(
    {"tiny_checkpoint", "tiny_timm_checkpoint"}
)  # fixtures that import torch and open_clip


# Files with tests that fit a memory map: importing umap-learn and compiling its layout costs ~4-5 s once
# per process, so the fast lane (`--dist loadgroup`) runs these files on one of its two workers.
MAP_FILES = frozenset(
    f"tests/{name}"
    for name in (
        "cli/test_faults.py",
        "cli/test_self_match.py",
        "cli/test_short_views.py",
        "data/test_video_data.py",
        "data/test_vocabulary.py",
        "evaluation/test_new_rule_calibration.py",
        "explain/test_explain.py",
        "memory/test_references.py",
        "viz/test_camera_video.py",
        "viz/test_contrast_recording.py",
        "viz/test_dense_neighbors.py",
        "viz/test_live.py",
        "viz/test_memory_map.py",
        "viz/test_notebook.py",
        "viz/test_viz.py",
    )
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The fast lane never imports torch (~8 s per worker): a test that asks for a torch fixture is slow."""
    for item in items:
        if TORCH_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)


def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """With `--dist loadgroup`: xdist's group scheduler, the MAP_FILES' tests one group, every other test
    its own. (Not `xdist_group` marks: xdist 3.8 names a group by rewriting `item._nodeid`, which pytest
    9.2 no longer reads, so the marks group nothing.)"""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class MapGroup(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return "map" if nodeid.partition("::")[0] in MAP_FILES else nodeid

    return MapGroup(config, log)


@pytest.fixture(scope="session")
def aha_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_aha_dataset(tmp_path_factory.mktemp("aha"))


@pytest.fixture(scope="session")
def pixels_memory_dir(aha_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The AHA fixture's failures as a saved pixels-encoder memory, built once for the whole run.

    Shared by every test that asks for it: a test that changes a memory saves its own copy first.
    """
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path_factory.mktemp("pixels-cache"))
    memory, _ = FailureMemory.build(load_dataset(aha_dataset), encoder)
    return memory.save(tmp_path_factory.mktemp("memory") / "pixels")


@pytest.fixture(scope="module")
def encoder(tmp_path_factory: pytest.TempPathFactory) -> CachedEncoder:
    """The weight-free pixels encoder, with an embedding cache of the test module's own."""
    return CachedEncoder(load_encoder("pixels"), cache_dir=tmp_path_factory.mktemp("embeddings"))


@pytest.fixture()
def pixels_memory(pixels_memory_dir: Path, aha_dataset: Path) -> FailureMemory:
    """The shared pixels memory, loaded afresh for each test so that no test sees another's changes; its
    images read from the AHA fixture, named as a verb's data names them (`FailureMemory.image_roots`)."""
    return FailureMemory.load(pixels_memory_dir, trusted=[aha_dataset])


@pytest.fixture()
def cache_dir(tmp_path: Path) -> Path:
    return tmp_path / "cache"


@pytest.fixture(scope="session")
def ray_cluster() -> Iterator[None]:
    """A local Ray cluster of 2 CPUs for this test process (`--ray auto` then uses it); ~15 s to start."""
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture
def ray_passes(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The frames sent to the Ray cluster, one count per Ray Data pass (`RayBackend.encode_all`)."""
    from robofailring.encoders.ray_backend import RayBackend

    passes: list[int] = []
    encode_all = RayBackend.encode_all

    def counted(self: RayBackend, frames: Sequence[Frame]) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        passes.append(len(frames))
        return encode_all(self, frames)

    monkeypatch.setattr(RayBackend, "encode_all", counted)
    return passes


TINY_CLIP = {
    "embed_dim": 16,
    "vision_cfg": {"image_size": 32, "layers": 1, "width": 32, "head_width": 16, "patch_size": 8},
    "text_cfg": {"context_length": 8, "vocab_size": 64, "width": 16, "heads": 1, "layers": 1},
}


TINY_TIMM_CLIP = {  # an image tower of timm's, as SigLIP's and the ConvNeXt CLIPs' are (`test_vit`: timm's own tiny ViT)
    "embed_dim": 16,
    "vision_cfg": {
        "timm_model_name": "test_vit",
        "timm_model_pretrained": False,
        "timm_pool": "avg",
        "timm_proj": "linear",
        "image_size": 32,
    },
    "text_cfg": TINY_CLIP["text_cfg"],
}


def _tiny_clip(factory: pytest.TempPathFactory, name: str, settings: dict[str, object]) -> tuple[Path, Path]:
    """A tiny random-initialised open_clip model `name` of `settings`, as a config JSON and a checkpoint."""
    import open_clip
    import torch

    folder = factory.mktemp(name)
    config = folder / f"{name}.json"
    config.write_text(json.dumps(settings))
    open_clip.add_model_config(config)
    torch.manual_seed(0)
    model = open_clip.create_model(name, pretrained=None)
    checkpoint = folder / "tiny.pt"
    torch.save({"state_dict": model.state_dict()}, checkpoint)
    return config, checkpoint


@pytest.fixture(scope="session")
def tiny_timm_checkpoint(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A tiny random-initialised open_clip model with a timm image tower, as a config JSON and a checkpoint."""
    return _tiny_clip(tmp_path_factory, "TinyTimm-test", TINY_TIMM_CLIP)


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A tiny random-initialised open_clip model written as a config JSON plus a torch checkpoint."""
    return _tiny_clip(tmp_path_factory, "TinyViT-test", TINY_CLIP)
