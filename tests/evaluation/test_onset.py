"""Alarms against a failure's onset, by hand and end to end: delays, premature alarms, explicit counts."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
from synthetic import write_project_dataset
from test_metrics import scored

from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.evaluation.job import EvaluateConfig, run_evaluation
from robofailring.evaluation.onset import onset_delay
from robofailring.evaluation.written import write_evaluation
from robofailring.memory.recipe import MemoryRecipe


def test_delay_after_onset_and_premature_alarms_by_hand() -> None:
    fires_at_2 = scored("f1", True, [0.5, 0.7, 0.93, 0.95, 0.9])
    fires_at_4 = scored("f2", True, [0.5, 0.5, 0.5, 0.5, 0.99])
    never = scored("f3", True, [0.1] * 5)
    runs = [
        replace(fires_at_2, onset_frame=1, fps=10.0),  # delay 1 frame, 0.1 s
        replace(fires_at_4, onset_frame=1, fps=10.0),  # delay 3 frames
        replace(fires_at_2, key="f4", onset_frame=3, fps=10.0),  # alarm 1 frame before onset
        replace(never, onset_frame=2),  # missed
        replace(fires_at_4, key="f5"),  # onset unknown: not counted
        scored("s1", False, [0.99] * 5),  # a success: no onset
    ]
    onset = onset_delay(runs, 0.92)
    assert (onset.failures, onset.known, onset.premature, onset.missed) == (5, 4, 1, 1)
    assert onset.delays == (1, 3) and onset.mean_frames == 2.0 and onset.median_frames == 2.0
    assert onset.delay_seconds == pytest.approx((0.1, 0.3)) and onset.mean_seconds == pytest.approx(0.2)
    assert onset.to_dict()["after_onset"] == 2 and onset.to_dict()["onset_known"] == 4
    # one delayed run without an fps: frames only
    frames_only = onset_delay([*runs[:1], replace(fires_at_4, onset_frame=0)], 0.92)
    assert frames_only.delays == (1, 4) and frames_only.delay_seconds is None
    assert (
        frames_only.to_dict()["delay_seconds_mean"] is None and "— (no fps)" in frames_only.markdown_cells()
    )
    assert onset_delay([never], 0.92).known == 0  # no onset known at all


def test_evaluation_reports_delay_and_premature_alarms_per_rule(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube", "push_cube"), episodes=2, length=6)
    manifest = json.loads((data / "manifest.json").read_text())
    onsets = {}
    for record in manifest["episodes"]:
        if record["outcome"] == "failure" and record["split"] == "test" and "slip" not in record["dir"]:
            onsets[f"{record['task']}/{record['dir']}"] = record["onset_frame"] = (
                2 if "grasp" in record["dir"] else 4
            )
    (data / "manifest.json").write_text(json.dumps(manifest))
    result = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data),
            threshold_policy=ThresholdPolicy(target_fpr=0.5),
            recipe=MemoryRecipe(failure_frames="end"),
            placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
            out=tmp_path / "out",
        )
    )
    json_path, md_path = write_evaluation(result, tmp_path / "out")
    report = json.loads(json_path.read_text())
    assert len(onsets) == 4  # grasp and wrong_object test failures of both tasks; slips: unknown
    # the paper rule at δ: recount from the per-trajectory t_det the JSON lists
    t_det = {row["key"]: row["t_det"] for row in report["trajectories"]}
    delays = [
        t_det[key] - onset for key, onset in onsets.items() if t_det[key] is not None and t_det[key] >= onset
    ]
    paper = report["rules"]["paper"]["onset"]
    assert paper["failures"] == 6 and paper["onset_known"] == 4
    assert paper["premature"] == sum(t_det[k] is not None and t_det[k] < o for k, o in onsets.items())
    assert paper["missed"] == sum(t_det[k] is None for k in onsets)
    assert paper["after_onset"] == len(delays) == 4 - paper["premature"] - paper["missed"]
    mean = sum(delays) / len(delays)
    assert paper["delay_frames_mean"] == pytest.approx(mean, abs=1e-6)
    assert paper["delay_seconds_mean"] == pytest.approx(mean / 10, abs=1e-6)  # the data's 10 fps
    for row in report["rules"].values():
        onset = row["onset"]
        assert onset["onset_known"] == 4 == onset["after_onset"] + onset["premature"] + onset["missed"]
    markdown = md_path.read_text()
    assert (
        "| rule | onset known / failures | alarm at or after onset | premature (before onset) |" in markdown
    )
    assert (
        f"| paper | 4 / 6 | {paper['after_onset']} | {paper['premature']} | {paper['missed']} |" in markdown
    )


def test_evaluation_without_onsets_says_so(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2, length=4)
    result = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data),
            threshold_policy=None,
            placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
            out=tmp_path / "out",
        )
    )
    assert all(rule.onset is not None and rule.onset.known == 0 for rule in result.rules.values())
    assert "No failure run has a known onset (`onset_frame`)" in result.to_markdown()
