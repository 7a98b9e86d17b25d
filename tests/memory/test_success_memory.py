"""Success memory and the contrast rule: S⁺ and C against brute force, storage, old folders, calibration."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import faiss
import numpy as np
import pytest
from synthetic import write_project_dataset

from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.calibration.conformal import conformal_threshold
from robofailring.calibration.job import calibrate_rules
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.model import Trajectory
from robofailring.data.selection import DataSelection
from robofailring.detection.rules import CONTRAST, PAPER
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import DataError, SettingError
from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
from robofailring.memory.pairs import pair_vectors
from robofailring.memory.recipe import MemoryRecipe
from robofailring.memory.success import INDEX, RUNS


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project_dataset(tmp_path_factory.mktemp("contrast") / "data", episodes=6)


@pytest.fixture(scope="module")
def built(
    dataset: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[FailureMemory, CachedEncoder, Path]:
    folder = tmp_path_factory.mktemp("built")
    out = folder / "memory"
    memory, _ = build_memory(
        BuildMemoryConfig(
            data=DataSelection(dataset),
            out=out,
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=folder / "cache"),
            split="train",
        )
    )
    return memory, CachedEncoder(load_encoder("pixels"), cache_dir=folder / "cache"), out


def _trajectories(dataset: Path, *, split: str, failure: bool) -> list[Trajectory]:
    return [t for t in load_dataset(dataset).select(split=split) if t.is_failure == failure]


def _brute_force(
    trajectory: Trajectory, train: list[Trajectory], *, exclude_own: bool, pairing: str
) -> dict[str, np.ndarray]:
    """S⁺ per view: max cosine over every frame of every same-task training success and the first frame of
    every same-task training failure (own episode out)."""
    raw = load_encoder("pixels")

    def pairs(frames: list[np.ndarray]) -> np.ndarray:
        embeddings = raw.encode(frames)
        return pair_vectors(np.repeat(embeddings[:1], len(frames), axis=0), embeddings, pairing=pairing)

    pool = np.concatenate(
        [
            pairs([f.load() for f in (run.views[view] if not run.is_failure else run.views[view][:1])])
            for run in train
            if run.task == trajectory.task and not (exclude_own and run.episode == trajectory.episode)
            for view in run.views
        ]
    )
    return {
        view: (pairs([f.load() for f in frames]) @ pool.T).max(axis=1)
        for view, frames in trajectory.views.items()
    }


def test_success_and_contrast_equal_brute_force(
    built: tuple[FailureMemory, CachedEncoder, Path], dataset: Path
) -> None:
    memory, encoder, _ = built
    train_successes = _trajectories(dataset, split="train", failure=False)
    train = list(load_dataset(dataset).select(split="train"))
    assert memory.successes is not None and len(memory.successes) == sum(
        len(t.views) * (1 if t.is_failure else t.length) for t in train
    )
    detector = FailureDetector(memory, encoder, k=2)
    assert detector.rule is CONTRAST  # the default with successes in the memory
    test_failure = _trajectories(dataset, split="test", failure=True)[0]
    own_success = train_successes[0]  # its own frames are in the success memory: leave-one-out hides them
    for trajectory, leave_out in ((test_failure, False), (own_success, True)):
        trace = detector.run(trajectory, leave_one_out=leave_out)
        expected = _brute_force(trajectory, train, exclude_own=leave_out, pairing=memory.pairing)
        for view in trace.views:
            np.testing.assert_allclose(trace.success_similarity[view], expected[view], atol=1e-5)
            np.testing.assert_allclose(
                trace.scores_of(CONTRAST)[view], trace.similarity[view] - expected[view], atol=1e-5
            )
            match = trace.nearest_success(view, 0)
            assert match is not None and match.run.task == trajectory.task
            assert not leave_out or match.run.episode != trajectory.episode
    # without leave-one-out, a training success finds itself: S⁺ = 1 at every frame
    itself = detector.run(own_success)
    np.testing.assert_allclose(itself.success_similarity["front"], 1.0, atol=1e-5)
    # the rule decides State_t: contrast against γ, fused over views
    stacked = np.stack([trace.scores_of(CONTRAST)[v] for v in trace.views]).max(axis=0)
    np.testing.assert_array_equal(trace.state, stacked >= trace.gamma)


def test_step_api_equals_the_trace(built: tuple[FailureMemory, CachedEncoder, Path], dataset: Path) -> None:
    memory, encoder, _ = built
    trajectory = _trajectories(dataset, split="test", failure=True)[1]
    detector = FailureDetector(memory, encoder, k=2, gamma=0.01)
    trace = detector.run(trajectory)
    session = detector.session(trajectory.task)
    for t in range(trace.length):
        step = session.step({view: frames[t] for view, frames in trajectory.views.items()})
        assert step.rule is CONTRAST and step.threshold == 0.01
        for view in trace.views:
            assert step.success_similarity[view] == pytest.approx(
                float(trace.success_similarity[view][t]), abs=1e-5
            )
            assert step.rule_scores["contrast"][view] == pytest.approx(
                float(trace.scores_of(CONTRAST)[view][t]), abs=1e-5
            )
    assert session.fired_at == trace.t_det


def test_saved_with_counts_and_old_folders_still_load(
    built: tuple[FailureMemory, CachedEncoder, Path], tmp_path: Path
) -> None:
    memory, encoder, out = built
    manifest = json.loads((out / "manifest.json").read_text())
    assert memory.successes is not None
    assert (
        manifest["successes"]["count"]
        == len(memory.successes)
        == len(FailureMemory.load(out).successes or [])
    )
    assert manifest["successes"]["tasks"] == {"pick_cube": 9, "push_cube": 9}  # 3 train runs x 3 views each
    # and the first frame of every training failure view: 2 tasks x 3 symbols x 3 train episodes x 3 views
    assert manifest["successes"]["failure_starts"] == 54 and manifest["successes"]["success_runs"] == 18
    from robofailring.memory.info import MemoryInfo

    info = MemoryInfo.read(out).to_dict()["successes"]
    assert info["frames"] == len(memory.successes) and info["offered"] == memory.successes.offered
    assert info["runs"] == 18 and {spec["kind"] for spec in info["index"].values()} == {"flat"}
    assert (
        f"{len(memory.successes)} frames kept of {memory.successes.offered} offered"
        in MemoryInfo.read(out).to_text()
    )
    loaded = FailureMemory.load(out)
    assert loaded.successes is not None
    np.testing.assert_array_equal(loaded.successes.vectors, memory.successes.vectors)
    assert loaded.successes.runs == memory.successes.runs
    # a folder written before success contrast: no success files, no manifest section
    old = tmp_path / "old"
    shutil.copytree(out, old)
    for path in old.glob("success*.faiss"):
        path.unlink()
    (old / RUNS).unlink()
    section = manifest.pop("successes")
    (old / "manifest.json").write_text(json.dumps(manifest))
    legacy = FailureMemory.load(old)
    assert legacy.successes is None and len(legacy) == len(memory)
    assert FailureDetector(legacy, encoder).rule is PAPER
    with pytest.raises(SettingError, match="--score paper"):
        FailureDetector(legacy, encoder, rule="contrast")
    # a success memory written as one flat `success.faiss` (before per-task index files) still loads
    flat = tmp_path / "flat"
    shutil.copytree(out, flat)
    for path in flat.glob("success.*.faiss"):
        path.unlink()
    whole = faiss.IndexFlatIP(memory.successes.dim)
    whole.add(memory.successes.vectors)
    faiss.write_index(whole, str(flat / INDEX))
    (flat / "manifest.json").write_text(
        json.dumps(manifest | {"successes": {k: v for k, v in section.items() if k != "index"}})
    )
    rebuilt = FailureMemory.load(flat).successes
    assert rebuilt is not None and rebuilt.runs == memory.successes.runs
    np.testing.assert_array_equal(rebuilt.vectors, memory.successes.vectors)
    # a success index that disagrees with the manifest is a clear error
    broken = tmp_path / "broken"
    shutil.copytree(out, broken)
    (broken / RUNS).write_text((out / RUNS).read_text().splitlines()[0] + "\n")
    with pytest.raises(Exception, match="success frames"):
        FailureMemory.load(broken)


def test_no_successes_builds_the_paper_memory(dataset: Path, tmp_path: Path) -> None:
    memory, _ = build_memory(
        BuildMemoryConfig(
            data=DataSelection(dataset),
            out=tmp_path / "m",
            recipe=MemoryRecipe.chosen("pixels"),
            placement=EncoderPlacement(cache_dir=tmp_path / "c"),
            split="train",
            success_memory=False,
        )
    )
    assert memory.successes is None and not (tmp_path / "m" / INDEX).exists()
    assert "successes" not in json.loads((tmp_path / "m" / "manifest.json").read_text())


def test_calibration_leaves_each_run_out(
    built: tuple[FailureMemory, CachedEncoder, Path], dataset: Path
) -> None:
    memory, encoder, _ = built
    successes = _trajectories(dataset, split="train", failure=False)  # 6 runs, all in the success memory
    detector = FailureDetector(memory, encoder, k=2)
    found = calibrate_rules(
        detector, successes, ThresholdPolicy(1 / 6)
    )  # n = 6 is just enough for α = 1/6 (needs 5)
    peaks = []
    train = list(load_dataset(dataset).select(split="train"))
    for trajectory in successes:
        splus = _brute_force(trajectory, train, exclude_own=True, pairing=memory.pairing)
        trace = detector.run(trajectory, leave_one_out=True)
        peaks.append(max(float(np.max(trace.similarity[v] - splus[v])) for v in trace.views))
    assert found[CONTRAST].threshold == pytest.approx(conformal_threshold(peaks, 1 / 6), abs=1e-5)
    assert found[CONTRAST].successes == 6
    assert math.isfinite(found[PAPER].threshold)
    with pytest.raises(
        DataError, match=r"needs at least 19 success runs.*smallest α these 6 runs allow is 0\.1429"
    ):
        calibrate_rules(detector, successes, ThresholdPolicy(0.05))
    at_best = calibrate_rules(
        detector, successes, ThresholdPolicy(0.05), at_best=True
    )  # small data: the smallest α, 1/7
    assert at_best[CONTRAST].target_fpr == pytest.approx(1 / 7) and at_best[CONTRAST].successes == 6
    assert at_best[CONTRAST].threshold == pytest.approx(conformal_threshold(peaks, 1 / 7), abs=1e-5)
    assert at_best[CONTRAST].threshold > max(peaks) - 1e-5 and at_best[CONTRAST].achieved_fpr == 0.0


def test_detect_json_has_both_rules_fields(
    built: tuple[FailureMemory, CachedEncoder, Path], dataset: Path
) -> None:
    from typer.testing import CliRunner

    from rfr_viz.cli.app import app

    memory, encoder, out = built
    trajectory = _trajectories(dataset, split="test", failure=True)[0]
    assert trajectory.source is not None
    args = ["detect", str(trajectory.source), "--memory", str(out), "--json", "--gamma", "0.05"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["score"] == "contrast" and report["threshold"] == 0.05
    trace = FailureDetector(memory, encoder, gamma=0.05).run(trajectory)
    assert report["t_det"] == trace.t_det
    for view, fields in report["views"].items():
        assert fields["failure_similarity"] == fields["similarity"]
        np.testing.assert_allclose(fields["success_similarity"], trace.success_similarity[view], atol=1e-6)
        np.testing.assert_allclose(fields["contrast"], trace.scores_of(CONTRAST)[view], atol=1e-6)
    paper = CliRunner().invoke(app, [*args[:-2], "--score", "paper", "--delta", "0.9"])
    assert paper.exit_code == 0 and json.loads(paper.stdout)["threshold"] == 0.9
