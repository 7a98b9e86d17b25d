"""`evaluate --test-data` with its own labels (`--test-labels`, issue 47 item 6): two LeRobot datasets both
number their episodes from 0, so one labels file cannot say the outcomes of both."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fault_helpers import cli, refused
from lerobot_writer import scene, write_lerobot_v3

from robofailring.data.model import Outcome
from robofailring.data.selection import DataSelection
from robofailring.evaluation.job import EvaluateConfig, select_splits

EPISODES = 6
TRAIN_FAILURES = (0, 1)  # the training set's failures: the same episode numbers succeed in the test set
TEST_FAILURES = (4, 5)


def _labels(path: Path, failures: tuple[int, ...]) -> Path:
    rows = [f"{e},failure,grasp_wp2" if e in failures else f"{e},success," for e in range(EPISODES)]
    path.write_text("episode_index,outcome,symbol\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def two_sets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("two-lerobot-sets")
    shape = {"lengths": (5,) * EPISODES, "tasks": ("pick up the cube",) * EPISODES, "cameras": ("front",)}
    return {
        "train": write_lerobot_v3(root / "train", size=32, codec="h264", **shape),  # type: ignore[arg-type]
        "test": write_lerobot_v3(
            root / "test",
            size=32,
            codec="h264",
            frame=lambda e, c, t: scene(e + EPISODES, c, t, 32),
            **shape,  # type: ignore[arg-type]
        ),
        "train_labels": _labels(root / "train.csv", TRAIN_FAILURES),
        "test_labels": _labels(root / "test.csv", TEST_FAILURES),
    }


def _outcomes(config: EvaluateConfig) -> dict[str, Outcome | None]:
    return {t.episode: t.outcome for t in select_splits(config).test}


def test_the_test_data_is_judged_by_its_own_labels(two_sets: dict[str, Path], tmp_path: Path) -> None:
    data = DataSelection(two_sets["train"], labels=two_sets["train_labels"])
    own = EvaluateConfig(
        data=data,
        out=tmp_path,
        test_data=data.other(two_sets["test"], labels=two_sets["test_labels"]),
        test_split="train",  # a LeRobot dataset's one split
    )
    assert _outcomes(own) == {
        f"episode_{e}": Outcome.FAILURE if e in TEST_FAILURES else Outcome.SUCCESS for e in range(EPISODES)
    }
    # without its own labels the training set's serve both, as before: episode 0 is a failure in each
    shared = EvaluateConfig(
        data=data, out=tmp_path, test_data=data.other(two_sets["test"]), test_split="train"
    )
    assert _outcomes(shared) == {
        f"episode_{e}": Outcome.FAILURE if e in TRAIN_FAILURES else Outcome.SUCCESS for e in range(EPISODES)
    }


def test_evaluate_takes_test_labels(two_sets: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "eval"
    result = cli(
        "evaluate",
        two_sets["train"],
        "--labels",
        two_sets["train_labels"],
        "--test-data",
        two_sets["test"],
        "--test-labels",
        two_sets["test_labels"],
        "--test-split",
        "train",
        "--target-fpr",
        "0.5",
        "--out",
        out,
        "--cache-dir",
        tmp_path / "cache",
    )
    assert result.exit_code == 0, result.output
    written = json.loads((out / "evaluation.json").read_text(encoding="utf-8"))
    assert (written["failures"], written["successes"]) == (2, 4)
    failures = {f"pick up the cube/episode_{e}" for e in TEST_FAILURES}
    for rule in written[
        "rules"
    ].values():  # every rule judged the test set's outcomes, not the training set's
        assert (rule["tp"] + rule["fn"], rule["fp"] + rule["tn"]) == (2, 4)
        assert set(rule["misses"]) <= failures and not set(rule["false_alarms"]) & failures


def test_test_labels_need_test_data(two_sets: dict[str, Path], tmp_path: Path) -> None:
    refused(
        cli(
            "evaluate",
            two_sets["train"],
            "--labels",
            two_sets["train_labels"],
            "--test-labels",
            two_sets["test_labels"],
            "--out",
            tmp_path / "eval",
        ),
        2,
        "--test-labels labels the dataset of --test-data",
    )
    assert not (tmp_path / "eval").exists()
