"""Encoding on a Ray cluster (`--ray`, docs/ray.md): the same embeddings and the same memory as this
process, the embedding cache shared both ways, and a cluster that cannot be reached named in one error."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from ports import free_port
from synthetic import write_project_dataset

from robofailring import FailureMemory, load_dataset
from robofailring.data.model import Frame
from robofailring.data.selection import DataSelection
from robofailring.encoders import open_encoder
from robofailring.encoders.placement import EncoderPlacement
from robofailring.encoders.ray_backend import RayBackend, _probe
from robofailring.errors import ClusterError
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.recipe import MemoryRecipe


def _frames(dataset: Path) -> list[Frame]:
    return [frame for t in load_dataset(dataset) for frames in t.views.values() for frame in frames]


@pytest.mark.slow  # the session's Ray cluster takes ~15 s to start, its actors a few seconds per pass
def test_ray_embeddings_equal_local_and_share_the_cache(
    ray_cluster: None, aha_dataset: Path, tmp_path: Path
) -> None:
    frames = _frames(aha_dataset)
    distinct = len({frame.content_key() for frame in frames})
    local = open_encoder("pixels", cache_dir=tmp_path / "local").encode_frames(frames)
    # half the frames already in the cache (encoded here): the cluster encodes only the other half
    shared = tmp_path / "shared"
    open_encoder("pixels", cache_dir=shared).encode_frames(frames[: len(frames) // 2])
    cached = len({frame.content_key() for frame in frames[: len(frames) // 2]})
    on_ray = open_encoder("pixels", cache_dir=shared, ray="auto")
    on_ray.prefetch(frames)
    assert on_ray.misses == distinct - cached > 0
    vectors = on_ray.encode_frames(frames)  # every one now read back from the cache
    assert on_ray.hits == len(frames)
    # equal to float32 rounding: a batch of other images changes BLAS's summation order (here too)
    np.testing.assert_allclose(vectors, local, atol=1e-6)
    # a second run, on the cluster or here, finds them all
    again = open_encoder("pixels", cache_dir=shared, ray="auto")
    again.prefetch(frames)
    assert again.misses == 0
    here = open_encoder("pixels", cache_dir=shared)
    np.testing.assert_array_equal(here.encode_frames(frames), vectors)
    assert (here.hits, here.misses) == (len(frames), 0)


@pytest.mark.slow
def test_build_memory_on_ray_is_the_local_memory(ray_cluster: None, tmp_path: Path) -> None:
    dataset = write_project_dataset(tmp_path / "data")  # failure and success runs
    built = {}
    for where, ray in (("local", None), ("ray", "auto")):
        config = BuildMemoryConfig(
            data=DataSelection(dataset),
            out=tmp_path / where,
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=tmp_path / f"cache-{where}", ray=ray),
        )
        build_memory(config)
        built[where] = FailureMemory.load(tmp_path / where)
    local, on_ray = built["local"], built["ray"]
    assert len(local) > 0 and on_ray.entries == local.entries
    np.testing.assert_allclose(on_ray.vectors, local.vectors, atol=1e-6)
    assert local.successes is not None and on_ray.successes is not None
    assert on_ray.successes.runs == local.successes.runs
    queries = local.vectors
    for task in local.tasks:
        (ray_similarity, ray_ids), (similarity, ids) = (
            on_ray.search(queries, task, 5),
            local.search(queries, task, 5),
        )
        np.testing.assert_allclose(ray_similarity, similarity, atol=1e-6)
        # the same neighbours, but for entries tied to the last bit (the same image in two runs)
        assert np.mean(ray_ids == ids) > 0.95
        tied = np.einsum("qd,qkd->qk", queries, local.vectors[ray_ids])
        np.testing.assert_allclose(tied, similarity, atol=1e-6)
        (ray_best, ray_rows), (best, rows) = (
            on_ray.successes.search(queries, task),
            local.successes.search(queries, task),
        )
        np.testing.assert_allclose(ray_best, best, atol=1e-6)
        assert np.mean(ray_rows == rows) > 0.95


@pytest.mark.slow
def test_tiny_clip_on_ray_matches_torch_here(
    ray_cluster: None, tiny_checkpoint: tuple[Path, Path], aha_dataset: Path, tmp_path: Path
) -> None:
    config, checkpoint = tiny_checkpoint
    spec = f"open_clip:{config}:{checkpoint}"
    frames = _frames(aha_dataset)[:40]
    local = open_encoder(spec, device="cpu", cache_dir=tmp_path / "local").encode_frames(frames)
    on_ray = open_encoder(spec, device="cpu", cache_dir=tmp_path / "ray", ray="auto")
    on_ray.prefetch(frames)
    assert on_ray.misses == len({frame.content_key() for frame in frames})
    np.testing.assert_allclose(on_ray.encode_frames(frames), local, atol=1e-6)


@pytest.mark.slow  # a fresh process that imports Ray and tries to connect (~2.5 s)
def test_unreachable_cluster_is_one_error_naming_its_address(aha_dataset: Path, tmp_path: Path) -> None:
    address = f"ray://127.0.0.1:{free_port()}"
    target, cache = str(tmp_path / "m"), str(tmp_path / "cache")
    command = ["build-memory", str(aha_dataset), "--out", target, "--cache-dir", cache, "--ray", address]
    result = subprocess.run(
        [sys.executable, "-m", "rfr_viz.cli.app", *command],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert result.returncode == 1, result.stderr
    assert (
        result.stderr.strip()
        .splitlines()[-1]
        .startswith(f"error: cannot reach the Ray cluster at --ray {address}")
    )
    assert "encoding" not in result.stderr  # refused before any frame was read
    assert not (tmp_path / "m").exists()


@pytest.mark.parametrize("address", ["", "nonsense", "host:port", "ray://:10001"])
def test_bad_cluster_addresses_are_refused(address: str) -> None:
    with pytest.raises(ClusterError, match="cluster address"):
        _probe(address) if address else RayBackend(address, spec="pixels", identity="pixels")


@pytest.mark.slow
def test_a_frame_no_worker_can_decode_is_the_data_error_naming_it(ray_cluster: None, tmp_path: Path) -> None:
    from robofailring.data.images import write_png
    from robofailring.errors import DataError

    frames = []
    for i in range(6):
        write_png(tmp_path / f"{i}.png", np.full((32, 32, 3), 40 * i, dtype=np.uint8))
        frames.append(Frame(path=tmp_path / f"{i}.png"))
    (tmp_path / "3.png").write_bytes(b"\x89PNG\r\n\x1a\n not an image")
    on_ray = open_encoder("pixels", cache_dir=tmp_path / "cache", ray="auto")
    with pytest.raises(DataError, match=r"3\.png") as raised:
        on_ray.prefetch(frames)
    assert "Ray" not in type(raised.value).__name__ and len(str(raised.value)) < 300


@pytest.mark.slow
def test_workers_loading_other_weights_stop_the_pass(ray_cluster: None, aha_dataset: Path) -> None:
    backend = RayBackend("auto", spec="pixels", identity="open_clip:ViT-B-32:openai")
    with pytest.raises(
        ClusterError, match=r"loaded encoder pixels as pixels\S*, not open_clip:ViT-B-32:openai"
    ):
        list(backend.encode_all(_frames(aha_dataset)[:4]))


def test_every_kind_of_frame_travels_to_a_worker_by_where_it_lives(tmp_path: Path) -> None:
    """Image files, arrays, HDF5 rows, bag messages and video frames pickle for a worker (a file's
    reader is not sent: the worker opens its own, shared by that file's frames) and read back the same."""
    import pickle

    from hdf5_writer import write_robomimic
    from lerobot_writer import encode_video
    from rosbag_writer import write_bag
    from synthetic import synthetic_frame

    from robofailring import load_trajectory
    from robofailring.data.images import write_png
    from robofailring.data.video import VideoFrames, open_video
    from robofailring.encoders.ray_backend import _sendable

    def image(camera: int, t: int) -> np.ndarray:
        return synthetic_frame("pick_cube", None, camera % 3, t, 10, size=32)

    write_png(tmp_path / "a.png", image(0, 0))
    hdf5 = write_robomimic(tmp_path / "x.hdf5", lambda _, c, t: image(c, t), demos=1, length=3)
    bag = write_bag(
        tmp_path / "bags" / "run_1", kind="mcap", topics=(("/cam", "rgb8"),), frames=image, count=3
    )
    encode_video(tmp_path / "v.mp4", [image(0, t) for t in range(3)], fps=10, codec="h264")
    frames = [
        Frame(path=tmp_path / "a.png"),
        Frame.from_array(image(1, 1)),
        *(f for t in load_dataset(hdf5).trajectories() for fs in t.views.values() for f in fs),
        *(f for fs in load_trajectory(bag).views.values() for f in fs),
        *VideoFrames(open_video(tmp_path / "v.mp4")),
    ]
    for frame in frames:
        frame.load()  # the file opened here first, as the driver's digest would
        sent = pickle.loads(_sendable(frame))
        assert sent.reference == frame.reference and sent.content_key() == frame.content_key()
        np.testing.assert_array_equal(sent.load(), frame.load())
