"""A script that calls generate_dataset with worker processes but no `__main__` guard gets an error
that says so, where the process pool used to start new workers forever (and hold CI past its limit)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = """
from pathlib import Path
from robofailring.sim import GenerateConfig, generate_dataset
generate_dataset(GenerateConfig(out=Path({out!r}), tasks=("pick_cube",), episodes=1, success_episodes=1,
                                image_size=32, frames=8, workers=2))
print("finished")
"""


def test_a_script_without_a_main_guard_is_told_to_add_one(tmp_path: Path) -> None:
    out = tmp_path / "data"
    script = tmp_path / "unguarded.py"
    script.write_text(SCRIPT.format(out=str(out)), encoding="utf-8")
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=240, cwd=tmp_path
    )
    assert done.returncode != 0
    assert "finished" not in done.stdout
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("robofailring.errors.SettingError: a simulation worker process stopped")
    assert 'if __name__ == "__main__":' in last and "workers=1" in last
    assert not out.exists()  # nothing half-written
    assert not [p for p in tmp_path.iterdir() if p.name not in {"unguarded.py"}]
