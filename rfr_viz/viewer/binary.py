"""The real Rerun viewer executable (inside the `rerun_cli` package), the Vulkan driver it needs headless, and
the environment it runs in."""

from __future__ import annotations

import ctypes.util
import glob
import os
from pathlib import Path
from typing import Final

from robofailring.errors import RoboFailRingError
from robofailring.extras import needs_extra

ICD_GLOBS: Final[tuple[str, ...]] = (
    "/usr/share/vulkan/icd.d/*.json",
    "/etc/vulkan/icd.d/*.json",
    "/usr/local/share/vulkan/icd.d/*.json",
)


class ViewerUnavailable(RoboFailRingError, RuntimeError):
    """The viewer cannot run here (no Vulkan driver, no viewer binary, a server that stopped): exit 1."""

    exit_code = 1  # an error of the environment, not of the input


def viewer_binary() -> Path:
    """The real viewer executable inside the `rerun_cli` package (not the Python console script)."""
    with needs_extra("viz"):
        import rerun_cli
    binary = Path(rerun_cli.__file__).parent / "rerun"
    if not binary.is_file():
        raise ViewerUnavailable(f"no viewer binary at {binary}")
    return binary


def check_vulkan() -> None:
    """Raise ViewerUnavailable unless a Vulkan loader and a driver (e.g. Mesa lavapipe) are installed."""
    if ctypes.util.find_library("vulkan") is None:
        raise ViewerUnavailable(
            "no Vulkan loader (libvulkan.so.1); install Mesa's software driver: "
            "apt-get install -y --no-install-recommends mesa-vulkan-drivers libvulkan1"
        )
    icds = [path for pattern in ICD_GLOBS for path in glob.glob(pattern)]
    if not icds and not os.environ.get("VK_ICD_FILENAMES") and not os.environ.get("VK_DRIVER_FILES"):
        raise ViewerUnavailable(
            "no Vulkan driver (ICD) found; install Mesa's software driver: "
            "apt-get install -y --no-install-recommends mesa-vulkan-drivers libvulkan1"
        )


def viewer_environment(runtime_dir: str) -> dict[str, str]:
    return {**os.environ, "CI": "1", "XDG_RUNTIME_DIR": runtime_dir, "RERUN_ANALYTICS": "0"}
