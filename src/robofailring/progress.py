"""Progress bars for long work (stderr, quiet when not a terminal unless forced)."""

from __future__ import annotations

import os
from typing import Any

from tqdm.auto import tqdm


def progress_bar(*, total: int | None, desc: str, unit: str = "it", disable: bool | None = None) -> Any:
    """A tqdm bar on stderr; `ROBOFAILRING_PROGRESS=0` silences it."""
    if disable is None:
        disable = os.environ.get("ROBOFAILRING_PROGRESS", "1") == "0"
    return tqdm(total=total, desc=desc, unit=unit, disable=disable, dynamic_ncols=True, leave=False)
