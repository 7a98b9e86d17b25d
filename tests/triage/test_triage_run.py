"""`run_triage` on real image episodes: each reference (the task's other runs, known-good runs, a
memory), what is not scored, and bad settings."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from synthetic import write_triage_memory, write_unlabelled_runs

from robofailring.data.model import Outcome, Trajectory
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig, Scoring
from robofailring.detection.detector import FailureDetector
from robofailring.encoders import CachedEncoder
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import DataError, SettingError
from robofailring.triage import TriageConfig, ranking_quality, run_triage
from robofailring.triage import job as triage_job
from robofailring.triage.reference import MEMORY, OTHERS, SUCCESSES
from robofailring.triage.scoring import EpisodeScore


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    return write_unlabelled_runs(tmp_path_factory.mktemp("runs") / "runs")


def _config(
    data: Path,
    tmp_path: Path,
    *,
    memory: Path | None = None,
    score: str | None = None,
    labels: Path | None = None,
    **changes: object,
) -> TriageConfig:
    detector = DetectorConfig(
        memory=memory, rule=score, placement=EncoderPlacement(cache_dir=tmp_path / "cache")
    )
    selection = DataSelection(data, labels=labels, task="pick_cube")
    return TriageConfig(data=selection, out=tmp_path / "out", detector=detector, **changes)  # type: ignore[arg-type]


def _failed(result_ranked: list, truth: dict[str, str]) -> list[bool]:
    return [truth[score.episode] != "success" for score in result_ranked]


def test_with_nothing_the_failures_stand_out_from_the_other_runs(runs, tmp_path: Path) -> None:
    data, truth = runs
    result = run_triage(_config(data, tmp_path))
    assert result.modes == {"pick_cube": OTHERS}
    assert "assumes most runs of the task succeeded" in result.notes[0]
    assert len(result.ranked) == len(truth)
    assert {s.episode for s in result.ranked[:3]} == {e for e, kind in truth.items() if kind != "success"}
    top = result.ranked[0]
    assert top.scored and 0 <= top.frame < 6 and top.view in ("front", "wrist")
    assert top.thumbnail is not None and top.thumbnail.load().shape == (32, 32, 3)
    assert top.normal_episode and top.normal_episode != top.episode  # its own episode left out
    assert top.failure_symbol == ""  # no failure memory: nothing to suggest
    assert ranking_quality(_failed(result.ranked, truth)).auc == 1.0


def test_known_good_runs_from_labels_and_a_labelled_failure(runs, tmp_path: Path) -> None:
    data, truth = runs
    labels = tmp_path / "labels.csv"
    good = [e for e, kind in truth.items() if kind == "success"][:5]
    failure = next(e for e, kind in truth.items() if kind == "grasp_wp2")
    with labels.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "outcome", "symbol"])
        writer.writerows([[e, "success", ""] for e in good] + [[failure, "failure", "grasp_wp2"]])
    result = run_triage(_config(data, tmp_path, labels=labels))
    assert result.modes == {"pick_cube": SUCCESSES}
    assert result.notes == []
    assert ranking_quality(_failed(result.ranked, truth)).auc == 1.0
    assert all(score.rule == "novelty" for score in result.ranked)  # a success memory judges by N = 1 − S⁺
    # the labelled failure names the nearest failure at every other episode's peak
    assert {s.failure_symbol for s in result.ranked if s.episode != failure} == {"grasp_wp2"}
    assert "grasp" in next(s for s in result.ranked if s.episode != failure).failure_description
    assert next(s for s in result.ranked if s.episode == failure).failure_symbol == ""  # its own, left out
    assert result.trajectories[f"pick_cube/{failure}"].outcome is Outcome.FAILURE


def test_known_good_runs_from_another_dataset(runs, tmp_path: Path) -> None:
    data, truth = runs
    good, _ = write_unlabelled_runs(tmp_path / "good", successes=4, failures=())
    result = run_triage(_config(data, tmp_path, known_good=good))
    assert result.modes == {"pick_cube": SUCCESSES}
    assert ranking_quality(_failed(result.ranked, truth)).auc == 1.0


def test_a_memory_judges_by_its_rules(runs, tmp_path: Path) -> None:
    data, truth = runs
    folder = write_triage_memory(tmp_path)
    result = run_triage(_config(data, tmp_path, memory=folder))
    assert result.modes == {"pick_cube": MEMORY}
    top = result.ranked[0]
    assert top.rule == "contrast" and top.rank_score > 3  # spreads above the median peak of its task
    assert truth[top.episode] != "success" and top.failure_symbol == "grasp_wp2"  # the one type it holds
    # contrast ranks a failure of a type the memory lacks low; the novelty rule does not
    novelty = run_triage(_config(data, tmp_path, memory=folder, score="novelty"))
    assert {s.rule for s in novelty.ranked} == {"novelty"}
    assert ranking_quality(_failed(novelty.ranked, truth)).auc == 1.0
    with pytest.raises(DataError, match="no run in memory"):
        run_triage(
            TriageConfig(
                data=DataSelection(data, task="push_cube"),
                out=tmp_path / "o2",
                detector=DetectorConfig(memory=folder),
            )
        )


def test_an_episode_too_short_to_score_ranks_last_and_is_listed(runs, tmp_path: Path) -> None:
    data, _ = write_unlabelled_runs(tmp_path / "runs", successes=5, failures=("grasp_wp2",))
    short = data / "run_99"
    short.mkdir()
    (data / "run_00" / "front_0.png").rename(short / "front_0.png")
    result = run_triage(_config(data, tmp_path))
    last = result.ranked[-1]
    assert last.episode == "run_99" and not last.scored
    assert any("run_99" in str(s.path) and "not scored" in s.reason for s in result.skipped_inputs)


def test_the_only_run_of_its_task_is_listed_as_not_scored(tmp_path: Path) -> None:
    data, _ = write_unlabelled_runs(tmp_path / "runs", successes=1, failures=())
    result = run_triage(_config(data, tmp_path))
    assert [s.scored for s in result.ranked] == [False]
    assert any(
        "holds nothing of task 'pick_cube' the novelty rule" in s.reason for s in result.skipped_inputs
    )


def test_the_reference_is_a_fixed_sample_when_a_task_has_many_runs(runs, tmp_path: Path) -> None:
    data, truth = runs
    first = run_triage(_config(data, tmp_path, reference_runs=6))
    again = run_triage(_config(data, tmp_path, reference_runs=6))
    assert "other 5 episode(s)" in first.notes[0]
    assert [s.episode for s in first.ranked] == [s.episode for s in again.ranked]
    assert len(first.ranked) == len(truth)


def test_bad_settings_fail_before_any_work(tmp_path: Path) -> None:
    with pytest.raises(SettingError, match="--memory and --successes"):
        TriageConfig(
            data=DataSelection(tmp_path),
            out=tmp_path / "o",
            detector=DetectorConfig(memory=tmp_path),
            known_good=tmp_path,
        )
    with pytest.raises(SettingError, match="--reference-runs"):
        TriageConfig(data=DataSelection(tmp_path), out=tmp_path / "o", reference_runs=1)
    with pytest.raises(SettingError, match="k"):
        TriageConfig(
            data=DataSelection(tmp_path), out=tmp_path / "o", detector=DetectorConfig(scoring=Scoring(k=0))
        )


def test_a_triage_stopped_half_way_resumes_from_the_embedding_cache(
    runs, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Stopped after 4 episodes (Ctrl-C), triage run again encodes only what the first run had not: over
    both runs every frame is encoded as often as in one uninterrupted run."""
    data, truth = runs
    folder = write_triage_memory(tmp_path / "built")
    whole = run_triage(_config(data, tmp_path / "whole", memory=folder)).detector.encoder
    score = triage_job.score_episode
    stopped: list[CachedEncoder] = []

    def stop_after_four(detector: FailureDetector, trajectory: Trajectory, *, mode: str) -> EpisodeScore:
        if detector.encoder.hits + detector.encoder.misses >= 4 * 2 * 6:  # 4 episodes of 2 views x 6 frames
            stopped.append(detector.encoder)
            raise KeyboardInterrupt
        return score(detector, trajectory, mode=mode)

    monkeypatch.setattr(triage_job, "score_episode", stop_after_four)
    with pytest.raises(KeyboardInterrupt):
        run_triage(_config(data, tmp_path / "split", memory=folder))
    monkeypatch.setattr(triage_job, "score_episode", score)
    resumed = run_triage(_config(data, tmp_path / "split", memory=folder))
    first = stopped[0]
    assert first.misses > 0 and resumed.detector.encoder.misses > 0
    assert first.misses + resumed.detector.encoder.misses == whole.misses
    assert resumed.detector.encoder.hits >= first.misses  # the first run's frames read from the cache
    assert len(resumed.ranked) == len(truth)
