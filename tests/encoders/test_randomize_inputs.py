"""`train-encoder --randomize` inputs, checked before anything is simulated or trained (no torch):
extra training data in the recipe, and data whose tasks the simulator does not have."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from synthetic import write_project_dataset

from robofailring.encoders.training import TrainEncoderConfig
from robofailring.errors import SettingError
from robofailring.jobs.train_encoder import TrainEncoderJob

PROBE = """
import json, sys
from typer.testing import CliRunner
from robofailring.cli.verbs import app
result = CliRunner().invoke(app, {args!r})
print(json.dumps({{"exit": result.exit_code, "output": result.output, "torch": "torch" in sys.modules}}))
"""


def test_extra_data_is_part_of_the_recipe(tmp_path: Path) -> None:
    base = TrainEncoderConfig(data=tmp_path / "data", out=tmp_path / "encoder")
    extra = replace(base, extra_data=(str(tmp_path / "random-1"),))  # type: ignore[arg-type]
    assert "extra_data" not in base.recipe()  # encoders trained without extra data keep their recipe
    assert extra.extra_data == (tmp_path / "random-1",)
    assert extra.recipe()["extra_data"] == [str((tmp_path / "random-1").resolve())]
    assert extra.recipe() != replace(base, extra_data=(tmp_path / "random-2",)).recipe()
    with pytest.raises(SettingError, match="both the training data and an extra dataset"):
        replace(base, extra_data=(tmp_path / "data",))
    with pytest.raises(SettingError, match="--randomize must be at least 0"):
        TrainEncoderJob(base, randomize=-1)


def test_randomize_refuses_data_of_tasks_the_simulator_does_not_have(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("fold_towel", "pick_cube"), episodes=2, length=4)
    out = tmp_path / "encoder"
    args = ["train-encoder", str(data), "--out", str(out), "--randomize", "8", "--epochs", "1"]
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(args=args)], capture_output=True, text=True, check=True
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["exit"] == 2
    message = " ".join(result["output"].split())
    assert "tasks ['fold_towel', 'pick_cube']" in message
    assert "simulator only ['pick_cube', 'push_cube', 'stack_cube', 'put_in_tray']" in message
    assert "cannot simulate ['fold_towel']" in message
    assert result["torch"] is False  # refused before torch was imported, let alone a frame trained on
    assert not out.exists()
