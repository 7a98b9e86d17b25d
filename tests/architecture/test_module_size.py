"""Every module of both packages stays small enough to read in one sitting: at most 400 lines (STYLE: small
modules, one concern each; a longer one is split along a real seam)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAX_LINES = 400


def test_no_module_is_longer_than_400_lines() -> None:
    modules = [*(ROOT / "src" / "robofailring").rglob("*.py"), *(ROOT / "rfr_viz").rglob("*.py")]
    assert len(modules) > 100  # both packages were found
    lengths = {path.relative_to(ROOT): len(path.read_text(encoding="utf-8").splitlines()) for path in modules}
    assert {path: lines for path, lines in lengths.items() if lines > MAX_LINES} == {}
