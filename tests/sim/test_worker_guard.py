"""A script that calls generate_dataset with worker processes but no `__main__` guard gets an error
that says so, where the process pool used to start new workers forever (and hold CI past its limit); an
image size the simulator cannot render is refused before any worker starts, not blamed on the guard."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from fault_helpers import cli
from hypothesis import example, given
from hypothesis import strategies as st

from robofailring.sim import GenerateConfig
from robofailring.sim.job import MAX_IMAGE_SIZE

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
    # the worker processes write to the same stderr, and one may still be exiting after the script's
    # own error is printed (CPython 3.11's pools can say "OSError: handle is closed" at exit), so the
    # script's error is looked for among the lines, not taken to be the last
    said = [
        line
        for line in done.stderr.splitlines()
        if line.startswith("robofailring.errors.SettingError: a simulation worker process stopped")
    ]
    assert said, done.stderr
    assert 'if __name__ == "__main__":' in said[0] and "workers=1" in said[0]
    assert not out.exists()  # nothing half-written
    assert not [p for p in tmp_path.iterdir() if p.name not in {"unguarded.py"}]


@pytest.fixture(scope="module")
def nowhere(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("sizes")


@given(st.integers(-(10**12), 10**12))
@example(100_000)  # issue 35, item 9: the worker died of bad_alloc, and that was blamed on a `__main__` guard
@example(MAX_IMAGE_SIZE + 1)
def test_generate_refuses_an_image_size_it_cannot_render_before_any_work(nowhere: Path, size: int) -> None:
    out = nowhere / f"data-{size}"
    if 16 <= size <= MAX_IMAGE_SIZE:
        assert GenerateConfig(out=out, image_size=size).image_size == size
        return
    result = cli("generate", "--out", out, "--image-size", size, "--tasks", "pick_cube")
    assert result.exit_code == 2 and isinstance(result.exception, SystemExit), result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "--image-size must be at" in errors[0] and str(size) in errors[0], (
        result.output
    )
    assert "__main__" not in result.output and not out.exists()
