"""What some tests need from the machine, and what a test does when it is missing.

`scripts/test.sh` sets all of it up (scripts/setup.sh --dev) and exports ROBOFAILRING_FULL_ENV=1;
CI sets CI=true. There a missing piece FAILS the test, saying what is missing and how to install
it; in a plain local `pytest` run the test is skipped instead.
"""

from __future__ import annotations

import importlib
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Final, NoReturn

import pytest

FULL_ENV: Final = "ROBOFAILRING_FULL_ENV"
SHARED_DATA_ENV: Final = "ROBOFAILRING_SHARED_DATA"
CHECKOUT: Final = Path(__file__).resolve().parents[1]


def full_lane() -> bool:
    """Whether the environment scripts/test.sh sets up is promised (scripts/test.sh, or CI)."""
    return os.environ.get(FULL_ENV) == "1" or os.environ.get("CI", "").lower() in ("true", "1")


def missing(what: str) -> NoReturn:
    """Fail (full lane) or skip (a plain local run) a test whose environment lacks `what`."""
    if full_lane():
        pytest.fail(f"{what} (the full lane needs it: {FULL_ENV}=1 or CI is set)", pytrace=False)
    pytest.skip(what, allow_module_level=True)


def require_module(name: str, install: str) -> ModuleType:
    """`name` imported, or `missing` saying what is not installed and how to install it (`install`): in
    place of pytest.importorskip, which skips in the full lane too."""
    try:
        return importlib.import_module(name)
    except ImportError as error:
        missing(f"{name} cannot be imported ({error}): {install}")


def require_viewer() -> None:
    """The headless Rerun viewer can start here: a Vulkan loader and driver (Mesa lavapipe)."""
    with viewer_available():
        pass


@contextmanager
def viewer_available() -> Iterator[None]:
    """Around anything that starts the headless Rerun viewer: no Vulkan driver is `missing`."""
    from rfr_viz.viewer.binary import ViewerUnavailable, check_vulkan

    try:
        check_vulkan()
        yield
    except ViewerUnavailable as error:
        missing(f"headless Rerun viewer unavailable: {error}")


def require_ffmpeg() -> None:
    if shutil.which("ffmpeg") is None:
        missing(
            "the Rerun viewer decodes H.264 with ffmpeg (>= 5.1), which is not installed: "
            "apt-get install -y --no-install-recommends ffmpeg"
        )


def chromium() -> str:
    """The headless browser that renders report.html."""
    names = ("chromium", "chromium-browser", "google-chrome")
    browser = next((found for name in names if (found := shutil.which(name))), None)
    if browser is None:
        missing("no Chromium to render report.html: apt-get install -y --no-install-recommends chromium")
    return browser


def shared_data(name: str) -> Path:
    """`<name>` in the project's shared data: $ROBOFAILRING_SHARED_DATA, else the nearest shared/data
    at or above the checkout (a worktree sits further down than the main checkout)."""
    if override := os.environ.get(SHARED_DATA_ENV):
        candidates = [Path(override) / name]
    else:
        candidates = [folder / "shared" / "data" / name for folder in (CHECKOUT, *CHECKOUT.parents)]
    found = next((path for path in candidates if path.is_dir()), None)
    if found is None:
        missing(
            f"the shared data folder {name} is not at {candidates[0]}"
            + ("" if override else " nor in any shared/data above this checkout")
            + f": put the workspace's shared/ folder beside the checkout or set {SHARED_DATA_ENV}"
        )
    return found
