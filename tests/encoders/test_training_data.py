"""What `train-encoder` trains on, read without torch: episodes whose names say neither task nor outcome
take both from `--labels` (its `task` column) or `--task`."""

from __future__ import annotations

from pathlib import Path

import pytest
from synthetic import write_labelled_runs
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring.data.selection import DataSelection
from robofailring.encoders.training import TrainEncoderConfig, training_samples
from robofailring.errors import DataError


def test_image_episodes_train_from_a_labels_file_with_a_task_column(tmp_path: Path) -> None:
    data, labels = write_labelled_runs(tmp_path / "runs", runs=6, length=4)
    with pytest.raises(DataError, match=r"cannot tell the task of 6 episode\(s\).*--labels file"):
        training_samples(TrainEncoderConfig(data=data, out=tmp_path / "encoder"))
    config = TrainEncoderConfig(
        data=DataSelection(data, labels=labels), out=tmp_path / "encoder", frame_stride=1
    )
    found = training_samples(config)
    # the hash split's training half: every run labelled, 2 views × 4 frames each
    assert found.trajectories >= 1 and not found.skipped and len(found.samples) == 8 * found.trajectories
    kinds = {sample.label.split("|")[0] for sample in found.samples}
    assert kinds <= {"success", "grasp", "slip"} and all(
        s.label.endswith(("|front", "|wrist")) for s in found.samples
    )
    assert config.recipe()["labels"] == str(labels.resolve()) and "task" not in config.recipe()
    # --task alone tells the task, not the outcome: nothing labelled to learn from
    with pytest.raises(DataError, match="no labelled frames in split 'train'"):
        training_samples(
            TrainEncoderConfig(data=DataSelection(data, task="pick_cube"), out=tmp_path / "encoder")
        )
    assert "labels" not in TrainEncoderConfig(data=data, out=tmp_path / "e").recipe()  # older recipes stay


def test_train_encoder_takes_labels_and_task() -> None:
    shown = CliRunner().invoke(app, ["train-encoder", "--help"], env={"COLUMNS": "200"})
    assert shown.exit_code == 0 and "--labels" in shown.output and "--task" in shown.output
