"""`--device` on the verbs (issue 50): a name that is no device is one line and status 2 for every runtime,
before the data or the memory is read."""

from __future__ import annotations

from pathlib import Path

import pytest
from fault_helpers import cli, refused


@pytest.mark.parametrize("device", ["npu", "bogus:7"])
@pytest.mark.parametrize("runtime", ["torch", "onnx", "onnx-int8", "openvino-int8"])
def test_the_verbs_refuse_a_device_before_reading_anything(
    device: str, runtime: str, data: Path, memory: Path, cache: list[str], tmp_path: Path
) -> None:
    """`--runtime onnx --device bogus:7` ran on the CPU without a word, `--device npu` ended in torch's
    traceback; now each is one line and status 2 for every runtime, before the data is read."""
    placement = ("--device", device, "--runtime", runtime, *cache)
    built = cli("build-memory", data, "--out", tmp_path / "new", *placement)
    refused(built, 2, f"--device {device!r} is not a device")
    assert not (tmp_path / "new").exists()
    episode = next(path for path in sorted(data.rglob("*")) if path.is_dir() and "episode" in path.name)
    refused(cli("detect", episode, "--memory", memory, *placement), 2, f"--device {device!r}")


def test_pixels_takes_a_gpu_device_but_not_a_malformed_one(
    data: Path, memory: Path, cache: list[str], tmp_path: Path
) -> None:
    """M4: `npu` was refused for pixels but `cuda:99999999999999999999` accepted without a word; pixels runs
    on the CPU whatever the device, so a well-formed GPU device is taken (docs/errors.md)."""
    huge = "cuda:99999999999999999999"
    built = cli(
        "build-memory", data, "--out", tmp_path / "new", "--encoder", "pixels", "--device", huge, *cache
    )
    refused(built, 2, f"--device {huge!r} is not a device", "a GPU's index is at most 2,147,483,647")
    assert not (tmp_path / "new").exists()
    episode = next(path for path in sorted(data.rglob("*")) if path.is_dir() and "episode" in path.name)
    refused(cli("detect", episode, "--memory", memory, "--device", huge, *cache), 2, f"--device {huge!r}")
    for device in ("cuda", "cuda:1", "mps"):
        made = cli(
            "build-memory",
            data,
            "--out",
            tmp_path / device,
            "--encoder",
            "pixels",
            "--device",
            device,
            *cache,
        )
        assert made.exit_code == 0 and (tmp_path / device / "manifest.json").is_file(), made.output
