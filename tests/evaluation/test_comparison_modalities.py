"""An encoder comparison compares encoders (issue 51 item 4): on data with the robot's signals each encoder's rows
are its cameras alone at its own calibrated thresholds, the fused row beside; fused, the signals' thresholds would
set every encoder's row alike."""

from __future__ import annotations

from pathlib import Path

import pytest
from synthetic import write_project_dataset

from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.jobs.compare_encoders import CompareEncodersConfig, compare_encoders, comparison_table


def test_two_encoders_differ_in_their_camera_rows_with_the_fused_row_beside(
    tmp_path: Path, tiny_checkpoint: tuple[Path, Path]
) -> None:
    config_json, checkpoint = tiny_checkpoint
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=6, length=8, signals=True)
    results = compare_encoders(
        CompareEncodersConfig(
            data=DataSelection(data),
            out=tmp_path / "out",
            encoders=("pixels", f"open_clip:{config_json}:{checkpoint}"),
            threshold_policy=ThresholdPolicy(0.34),
            placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
        )
    )
    cameras = [result.modalities["contrast"]["cameras"].result for result in results]
    fused = [result.modalities["contrast"]["both"].result for result in results]
    assert cameras[0].threshold != cameras[1].threshold  # each encoder's own camera threshold
    assert (cameras[0].auc, cameras[0].recall) != (cameras[1].auc, cameras[1].recall)
    for result, camera, both in zip(results, cameras, fused, strict=True):
        assert both.threshold == result.rules["contrast"].threshold and camera.calibrated
    table = comparison_table(results)
    rows = [line for line in table.splitlines() if "| contrast |" in line]
    assert [row.split(" | ")[3] for row in rows] == ["cameras", "both", "cameras", "both"]
    camera_rows = [row.split(" | ", 2)[2] for row in rows[::2]]
    assert camera_rows[0] != camera_rows[1]
    assert f"γ = {cameras[1].threshold:.4f}" in rows[2] and f"{100 * cameras[1].recall:.2f}" in rows[2]
    assert pytest.approx(results[0].modalities["contrast"]["signals"].result.threshold) == (
        results[1].modalities["contrast"]["signals"].result.threshold
    )  # the signals alone do not depend on the encoder
