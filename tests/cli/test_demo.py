"""The demo pipeline and the false-alarm review, end to end on a tiny simulated set."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import pytest

from rfr_viz.jobs.demo import DemoConfig, DemoResult, _trained_encoder, run_demo, simulate_datasets
from rfr_viz.jobs.review import ReviewConfig, review
from rfr_viz.viewer.rrd import verify_recording
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import DataError

pytestmark = pytest.mark.slow  # simulation or end-to-end: the full lane only (scripts/test.sh)


def tiny_demo(root: Path, out: str) -> DemoConfig:
    """One task, few and small episodes: the whole pipeline in seconds."""
    return DemoConfig(
        out=root / out,
        data_dir=root / "data",
        tasks=("pick_cube",),
        episodes=2,
        success_episodes=4,  # two training successes: each is contrasted with the other
        ood_episodes=1,
        image_size=32,
        frames=8,
        workers=1,
        randomize=8,  # one randomised-look episode per kind
        threshold_policy=ThresholdPolicy(target_fpr=0.5),
        placement=EncoderPlacement(cache_dir=root / "cache"),
    )


@pytest.fixture(scope="module")
def demo(
    tmp_path_factory: pytest.TempPathFactory, tiny_checkpoint: tuple[Path, Path]
) -> tuple[Path, DemoResult]:
    root = tmp_path_factory.mktemp("demo")
    clip = "open_clip:{}:{}".format(
        *tiny_checkpoint
    )  # another encoder for the comparison (a pretrained one's place)
    return root, run_demo(replace(tiny_demo(root, "out"), compare_with=(clip, "pixels")), say=lambda _: None)


def test_demo_writes_everything_it_names(demo: tuple[Path, DemoResult]) -> None:
    root, result = demo
    out = root / "out"
    assert [e.name for e in result.evaluations] == ["in-distribution", "out-of-distribution"]
    for name in ("in-distribution", "out-of-distribution"):
        report = json.loads((out / f"{name}.json").read_text())
        assert report["target_fpr"] == 0.5 and set(report["rules"]) == {"paper", "contrast", "novelty"}
        assert report["calibrated"] is True and [r["delta"] for r in report["paper_deltas"]] == [
            0.85,
            0.9,
            0.92,
            0.95,
        ]
    manifest = json.loads((out / "memory" / "manifest.json").read_text())
    assert (
        manifest["calibration"]["target_fpr"] == 0.5
        and manifest["calibration"]["rules"]["paper"]["achieved_fpr"] == 0.0
    )
    verify_recording(result.summary)
    recorded = result.recordings
    assert recorded, "the demo wrote no trajectory recording"
    for kind, path in recorded.items():
        assert kind in {"detection", "false-alarm", "miss"} and path.name.startswith(kind)
        verify_recording(path)
    missing = {"detection", "false-alarm", "miss"} - set(recorded)
    assert len(result.notes) == len(missing)
    assert result.report == out / "report.html"
    page = result.report.read_text(encoding="utf-8")
    linked = {out / href for href in re.findall(r'href="([^"]+)"', page)}
    assert linked == {result.summary, *recorded.values()} and all(p.is_file() for p in linked)
    assert page.count("<h2>in-distribution") == 1 and page.count("<h2>out-of-distribution") == 1
    # the simulated datasets are cached: a second run (its datasets step, not the whole pipeline again)
    # does not simulate again
    stamp = (root / "data" / "sim-id" / "manifest.json").stat().st_mtime_ns
    ood_stamp = (root / "data" / "sim-ood" / "manifest.json").stat().st_mtime_ns
    assert simulate_datasets(tiny_demo(root, "out2"), root / "data") == (
        root / "data" / "sim-id",
        root / "data" / "sim-ood",
    )
    assert (root / "data" / "sim-id" / "manifest.json").stat().st_mtime_ns == stamp
    assert (root / "data" / "sim-ood" / "manifest.json").stat().st_mtime_ns == ood_stamp


def test_review_replays_the_listed_trajectories(demo: tuple[Path, DemoResult]) -> None:
    root, _ = demo
    out = root / "out"
    evaluation = out / "out-of-distribution.json"
    report = json.loads(evaluation.read_text())
    contrast = report["rules"]["contrast"]
    cases = [
        ("false-alarms", None, contrast["false_alarms"]),  # the default: the contrast rule's
        ("misses", None, contrast["misses"]),
        ("false-alarms", "paper", [row["key"] for row in report["false_alarms"]]),
    ]
    for kind, score, listed in cases:
        result = review(
            ReviewConfig(
                data=DataSelection(root / "data" / "sim-ood"),
                evaluation=evaluation,
                kind=kind,
                out=root / "review" / str(score),
                detector=DetectorConfig(rule=score, placement=EncoderPlacement(cache_dir=root / "cache")),
            )
        )
        assert len(result.recordings) == len(listed)
        for path in result.recordings:
            assert path.parent.name == kind
            verify_recording(path)
    with pytest.raises(DataError, match="not one of"):
        review(ReviewConfig(data=DataSelection(root), evaluation=evaluation, kind="everything"))
    with pytest.raises(DataError, match="not an evaluation"):
        review(ReviewConfig(data=DataSelection(root), evaluation=out / "memory" / "manifest.json"))


def test_demo_leads_with_its_trained_encoder_and_compares_it_with_pixels_and_more(
    demo: tuple[Path, DemoResult],
) -> None:
    root, result = demo
    comparison = result.comparison
    assert comparison is not None and comparison.table_path == root / "out" / "encoders" / "comparison.md"
    encoders = [r.encoder for r in comparison.results]
    assert encoders[0].startswith("trained:cnn4-64px-256d:") and encoders[1].startswith("pixels")
    assert len(encoders) == 3 and encoders[2].startswith("open_clip:TinyViT-test:file-")  # pixels once
    # the headline: the demo's memory, tables and recordings are the trained encoder's
    assert result.encoder == f"trained:{root / 'data' / 'trained-encoder'}"
    assert all(e.encoder == encoders[0] for e in result.evaluations)
    manifest = json.loads((root / "out" / "memory" / "manifest.json").read_text())
    band = manifest["calibration"]["rules"]["contrast"].get("band")
    assert manifest["encoder"] == encoders[0]
    assert (
        band is None if manifest["calibration"]["successes"] < 10 else band["kind"] == "shift"
    )  # 10+ fit one
    assert (manifest["failure_frames"], manifest["pairing"]) == ("dense", "change")
    # three encoders: the paper rule fused, the contrast and novelty rules their cameras alone with the fused row beside
    table = comparison.table_path.read_text()
    assert table.count("| `") == 3 * 5 and table.count("| cameras |") == 3 * 2
    trained = json.loads((root / "data" / "trained-encoder" / "encoder.json").read_text())
    assert trained["training"]["recipe"]["split"] == "train"
    assert trained["training"]["recipe"]["data"] == str((root / "data" / "sim-id").resolve())
    (randomized,) = (root / "data" / "randomized").iterdir()  # simulated beside the demo's sets
    assert trained["training"]["extra_data"] == [
        {"data": str(randomized.resolve()), "trajectories": 8, "frames": 8 * 3 * 4}  # 8 frames, stride 2
    ]
    assert comparison.recordings
    for path in comparison.recordings:
        verify_recording(path)
    # a second demo reuses the trained encoder (same recipe, same frames) instead of training again
    # (its training step only: the comparison itself ran above)
    weights = root / "data" / "trained-encoder" / "weights.pt"
    stamp = weights.stat().st_mtime_ns
    said: list[str] = []
    _trained_encoder(tiny_demo(root, "out3"), root / "data" / "sim-id", root / "data", said.append)
    assert weights.stat().st_mtime_ns == stamp and said[-1].startswith("reusing the trained encoder")
