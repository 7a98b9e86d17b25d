"""Dataset layouts (docs/data.md, "Data layouts read"): one module per layout, each registering itself.

Every module of this package is imported here, so each layout module's `register(Layout(...))` has run
before a root is opened; `LAYOUTS` is the registered layouts in their detection order (each layout's
`detect_order`) and `LAYOUTS_HELP` the "matches no known dataset layout" error's list. A new layout is one
module in this folder (docs/architecture.md, "Adding a layout").
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Final

for _module in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_module.name}")

from robofailring.data.layouts.aha import AHA_FAILURES, parse_aha_name  # noqa: E402
from robofailring.data.layouts.loading import Dataset, detect_layout, load_dataset, load_trajectory  # noqa: E402
from robofailring.data.layouts.maniskill import MANISKILL_FAILURES  # noqa: E402
from robofailring.data.layouts.project import (  # noqa: E402
    PROJECT_FORMAT,
    PROJECT_MANIFEST,
    read_project_manifest,
)
from robofailring.data.layouts.registry import Layout, in_detection_order, layouts_help  # noqa: E402

LAYOUTS: Final[tuple[Layout, ...]] = in_detection_order()
LAYOUTS_HELP: Final[str] = layouts_help()

__all__ = [
    "AHA_FAILURES",
    "LAYOUTS",
    "LAYOUTS_HELP",
    "MANISKILL_FAILURES",
    "PROJECT_FORMAT",
    "PROJECT_MANIFEST",
    "Dataset",
    "Layout",
    "detect_layout",
    "load_dataset",
    "load_trajectory",
    "parse_aha_name",
    "read_project_manifest",
]
