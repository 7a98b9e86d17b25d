"""The library is usable without Rerun and without the heavy optional parts: importing it loads none."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("rerun", "umap", "pybullet", "torch", "open_clip", "av", "httpx")


def test_import_robofailring_loads_no_heavy_package() -> None:
    probe = (
        "import json, sys; import robofailring; "
        f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & set({list(HEAVY)!r}))))"
    )
    loaded = json.loads(
        subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True).stdout
    )
    assert loaded == []
