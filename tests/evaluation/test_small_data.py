"""Evaluation on too few success runs for α (14 labelled rollouts): every figure that can be known, the
level each threshold fell back to, the plain statement that no FPR guarantee holds, and cross-validation
over every labelled run."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from synthetic import csv_rows, write_labelled_runs, write_project_dataset
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring import CachedEncoder, FailureDetector, load_dataset, load_encoder
from robofailring.calibration.conformal import auc
from robofailring.calibration.job import calibrate_rules
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.rules import PAPER
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import DataError, SettingError
from robofailring.evaluation.folds import FoldPlan, assign_folds
from robofailring.evaluation.job import EvaluateConfig, run_evaluation, select_splits
from robofailring.evaluation.written import write_evaluation
from robofailring.memory.builder import Provenance, build_memories

RUNS = 14  # 7 failures, 7 successes, one task


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return write_labelled_runs(tmp_path_factory.mktemp("small") / "runs", runs=RUNS)


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("cache")


def test_too_few_successes_give_every_figure_and_say_no_guarantee_holds(
    runs: tuple[Path, Path], cache: Path, tmp_path: Path
) -> None:
    data, labels = runs
    config = EvaluateConfig(
        data=DataSelection(data, labels=labels),
        threshold_policy=ThresholdPolicy(target_fpr=0.05),
        placement=EncoderPlacement(cache_dir=cache),
        out=tmp_path,
    )
    splits = select_splits(config)
    n = sum(not t.is_failure for t in splits.train)
    assert 1 <= n < 19  # too few for α = 5 %: today's error, "needs at least 19 success runs"
    result = run_evaluation(config)
    json_path, md_path = write_evaluation(result, tmp_path)
    report, markdown = json.loads(json_path.read_text()), md_path.read_text()
    assert set(report["rules"]) == {"paper", "contrast", "novelty"} and report["fpr_guarantee"] is False
    failures, successes = result.failures, result.successes
    for name, row in report["rules"].items():
        # the smallest α n runs allow: 1/(n+1), its threshold just above the highest calibration peak
        assert row["target_fpr"] == pytest.approx(1 / (n + 1)) and row["fpr_spread"]["successes"] == n
        assert row["tp"] + row["fn"] == failures and row["fp"] + row["tn"] == successes
        low, high = row["auc_interval"]
        assert 0.0 <= low <= row["auc"] <= high <= 1.0
        assert f"| {name} | " in markdown and f"| {100 / (n + 1):.3g} | " in markdown
    assert "**No false-positive-rate guarantee holds here.**" in markdown
    assert "needs at least 19 training success runs" in markdown
    assert f"- paper, contrast, novelty: {n} calibration run(s), α = {100 / (n + 1):.3g} %" in markdown
    assert "cross-validate with `--folds loo`" in markdown
    # enough runs for the asked α: calibrated at it, and nothing said about a shortfall
    enough = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data, labels=labels),
            threshold_policy=ThresholdPolicy(target_fpr=1 / (n + 1)),
            placement=EncoderPlacement(cache_dir=cache),
            out=tmp_path / "enough",
        )
    )
    assert enough.fpr_guarantee and "guarantee holds here" not in enough.to_markdown()


def test_a_rule_no_training_success_could_calibrate_is_left_out(
    runs: tuple[Path, Path], tmp_path: Path
) -> None:
    """The successes are runs of a task without failures: S⁻, and with it the paper and contrast rules, has
    nothing to score them by; the novelty rule (1 − S⁺) has."""
    data, labels = runs
    apart = tmp_path / "labels.csv"
    rows = labels.read_text().splitlines()
    apart.write_text(
        "\n".join(
            [rows[0], *(r.replace(",pick_cube", ",push_cube") if ",failure," in r else r for r in rows[1:])]
        )
    )
    result = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data, labels=apart),
            placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
            out=tmp_path / "out",
        )
    )
    assert list(result.rules) == ["novelty"] and result.uncalibrated == ["paper", "contrast"]
    assert result.to_dict()["uncalibrated_rules"] == ["paper", "contrast"] and not result.fpr_guarantee
    assert "- paper: none of the training success runs could be scored by it" in result.to_markdown()
    # one training success per task and no failure: nothing scores them at all
    lone = write_project_dataset(tmp_path / "lone", tasks=("pick_cube", "push_cube"), symbols=(), episodes=2)
    with pytest.raises(DataError, match="none of the 2 training success runs could be scored"):
        run_evaluation(
            EvaluateConfig(
                data=DataSelection(lone),
                placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
                out=tmp_path / "lone-out",
            )
        )


def test_leave_one_episode_out_pools_every_labelled_run(
    runs: tuple[Path, Path], cache: Path, tmp_path: Path
) -> None:
    data, labels = runs
    config = EvaluateConfig(
        data=DataSelection(data, labels=labels),
        placement=EncoderPlacement(cache_dir=cache),
        out=tmp_path,
        folds=FoldPlan.parse("loo"),
    )
    crossed = run_evaluation(config).cross_validation
    assert crossed is not None and crossed.folds == RUNS and not crossed.guaranteed
    assert (crossed.failures, crossed.successes, crossed.not_judged) == (7, 7, {})
    summary = crossed.to_dict()
    assert summary["folds"] == "loo" and summary["fpr_guarantee"] is False
    for pooled in crossed.rules.values():
        assert pooled.judged == RUNS and pooled.tp + pooled.fn == 7 and pooled.fp + pooled.tn == 7
        # a held-out failure leaves 7 successes to calibrate on (α = 1/8), a held-out success 6 (α = 1/7)
        assert sorted(pooled.calibration_runs) == [6] * 7 + [7] * 7
        assert sorted(set(pooled.levels)) == pytest.approx([1 / 8, 1 / 7])
        assert pooled.auc == auc(pooled.failure_peaks, pooled.success_peaks)
    # one fold by hand: the other 13 runs' memory and δ judge run_00, and its peak is among the pooled ones
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=cache)
    every = list(load_dataset(data, labels=labels))
    held, others = every[0], every[1:]
    memory, _ = build_memories(others, encoder, provenance=Provenance(data=data, encoder="pixels"))
    detector = FailureDetector(memory, encoder)
    found = calibrate_rules(
        detector, [t for t in others if not t.is_failure], ThresholdPolicy(0.05, band="shift"), at_best=True
    )
    assert found[PAPER].target_fpr == pytest.approx(1 / 7)  # run_00 is a success: 6 others
    trace = detector.run(held)
    paper_peak = max(float(values.max()) for values in trace.judged_scores_of(PAPER).values())
    assert any(abs(peak - paper_peak) < 1e-6 for peak in crossed.rules["paper"].success_peaks)
    markdown = "\n".join(crossed.to_markdown())
    assert (
        "Cross-validation over every labelled run (14: 7 failure, 7 success; leave-one-episode-out"
        in markdown
    )
    assert "| 12.5–14.3 | 6–7 |" in markdown
    assert "**No false-positive-rate guarantee holds for the cross-validation:**" in markdown
    assert "some folds had fewer (" in markdown and " judged at a larger α)" in markdown


def test_folds_deal_failures_and_successes_evenly(runs: tuple[Path, Path]) -> None:
    data, labels = runs
    every = list(load_dataset(data, labels=labels))
    folds = assign_folds(every, FoldPlan(3))
    assert sorted(len(fold) for fold in folds) == [4, 5, 5]
    assert sorted(t.key for fold in folds for t in fold) == sorted(t.key for t in every)
    assert all(
        sum(t.is_failure for t in fold) >= 2 and sum(not t.is_failure for t in fold) >= 2 for fold in folds
    )
    assert [[t.key for t in fold] for fold in folds] == [
        [t.key for t in fold] for fold in assign_folds(every, FoldPlan(3))
    ]
    assert [len(fold) for fold in assign_folds(every, FoldPlan(None))] == [1] * RUNS


@given(st.text(max_size=8))
def test_fold_plans_parse_or_say_what_they_take(text: str) -> None:
    try:
        plan = FoldPlan.parse(text)
    except SettingError as error:
        assert "--folds takes loo or a whole number ≥ 2" in str(error)
    else:
        assert plan.count is None or plan.count >= 2


def test_folds_refuse_a_given_memory(tmp_path: Path) -> None:
    assert FoldPlan.parse(" LOO ") == FoldPlan(None) and FoldPlan.parse("5") == FoldPlan(5)
    with pytest.raises(SettingError, match="--folds builds a memory"):
        EvaluateConfig(
            data=DataSelection(tmp_path),
            memory=tmp_path / "m",
            out=tmp_path / "out",
            folds=FoldPlan(5),
        )


def test_evaluate_folds_on_the_command_line(runs: tuple[Path, Path], cache: Path, tmp_path: Path) -> None:
    data, labels = runs
    out = tmp_path / "eval"
    args = ["evaluate", str(data), "--labels", str(labels), "--out", str(out), "--folds", "4"]
    result = CliRunner().invoke(app, [*args, "--cache-dir", str(cache)])
    assert result.exit_code == 0, result.output
    assert "No false-positive-rate guarantee holds here." in result.output
    assert "(14: 7 failure, 7 success; 4 folds, failures and successes dealt evenly)" in result.output
    crossed = json.loads((out / "evaluation.json").read_text())["cross_validation"]
    assert crossed["fold_count"] == 4 and all(row["judged"] == RUNS for row in crossed["rules"].values())
    refused = CliRunner().invoke(app, [*args[:-1], "1", "--cache-dir", str(cache)])
    assert refused.exit_code != 0 and "--folds takes loo or a whole number ≥ 2, got '1'" in refused.output


def test_folds_still_cross_validate_when_the_split_gives_no_held_out_evaluation(
    runs: tuple[Path, Path], cache: Path, tmp_path: Path
) -> None:
    """A handful of runs whose successes all sit in the test split: nothing to calibrate the held-out
    evaluation on. `--folds` needs no split, so the cross-validation is written, said, status 3."""
    data, labels = runs
    rows = csv_rows(labels)
    split_labels = tmp_path / "split-labels.csv"
    with split_labels.open("w", newline="", encoding="utf-8") as file:
        writer = csv.DictWriter(file, fieldnames=[*rows[0], "split"])
        writer.writeheader()
        writer.writerows({**row, "split": "train" if row["outcome"] == "failure" else "test"} for row in rows)
    args = ["evaluate", str(data), "--labels", str(split_labels), "--cache-dir", str(cache)]
    alone = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "eval"), "--folds", "loo"])
    assert alone.exit_code == 3, alone.output
    assert "warning: no held-out evaluation (no success trajectory of the memory's tasks" in alone.stderr
    written = json.loads((tmp_path / "eval" / "evaluation.json").read_text())
    assert written["held_out_evaluation"] is None and "split 'train'" in written["held_out_not_made"]
    crossed = written["cross_validation"]
    assert crossed["fold_count"] == RUNS and (crossed["failures"], crossed["successes"]) == (7, 7)
    assert all(row["judged"] == RUNS for row in crossed["rules"].values())
    markdown = (tmp_path / "eval" / "evaluation.md").read_text()
    assert "cross-validation only" in markdown and "| paper | 14 |" in markdown
    page = (tmp_path / "eval" / "report.html").read_text()
    assert "<svg" not in page and "No held-out evaluation" in page
    assert not (tmp_path / "eval" / "evaluation.rrd").exists()
    # without --folds the split's error is the command's, as before
    refused = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "plain")])
    assert refused.exit_code == 2 and "error: no success trajectory of the memory's tasks" in refused.stderr
