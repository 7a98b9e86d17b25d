"""The triage job's outputs read back: triage.rrd (every curve, each peak frame, the rank order), the
replays opening at each peak, triage.html and triage.csv, and what it refuses to write over."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from rrd import batches, blueprint_names, columns, entity_paths, properties, static_value
from synthetic import csv_rows, write_unlabelled_runs

from rfr_viz.jobs.triage import triage
from rfr_viz.paths import TRIAGE_RANKING, TRIAGE_SCORES, triage_curve, triage_episode
from rfr_viz.viewer.control import verify_recording
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import OutputError
from robofailring.triage import TriageConfig


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory):
    root = tmp_path_factory.mktemp("triage")
    data, truth = write_unlabelled_runs(root / "runs", successes=7, failures=("grasp_wp2",))
    config = TriageConfig(
        data=DataSelection(data, task="pick_cube"),
        out=root / "out",
        detector=DetectorConfig(placement=EncoderPlacement(cache_dir=root / "cache")),
    )
    return config, truth, triage(config, replays=2)


def test_one_recording_browses_every_episode(written) -> None:
    _, truth, outcome = written
    ranked = outcome.result.ranked
    paths = entity_paths(outcome.recording)
    for score in ranked:
        assert triage_curve(score.rank) in paths
        assert f"{triage_episode(score.rank)}/peak" in paths
    top = ranked[0]
    assert truth[top.episode] == "grasp_wp2"
    curve = columns(outcome.recording, triage_curve(1))
    scalars = [row[0] for row in curve["Scalars:scalars"] if row]
    assert scalars == pytest.approx(top.curve.tolist(), rel=1e-5)
    assert curve["frame"][: len(scalars)] == list(range(len(scalars)))
    jpeg = static_value(outcome.recording, f"{triage_episode(1)}/peak", "EncodedImage:blob")
    assert bytes(jpeg[0][:3]) == b"\xff\xd8\xff"
    info = static_value(outcome.recording, f"{triage_episode(1)}/info", "TextDocument:text")[0]
    assert f"#1 pick_cube/{top.episode}" in info and f"frame {top.frame}" in info and "open" in info
    table = static_value(outcome.recording, TRIAGE_RANKING, "TextDocument:text")[0]
    assert table.index(top.episode) < table.index(ranked[-1].episode)
    assert "assumes most runs of the task succeeded" in table
    bars = [b for b in batches(outcome.recording, TRIAGE_SCORES) if "BarChart:values" in b.schema.names]
    values = bars[0].to_pydict()["BarChart:values"][0][0]["buffer"]
    assert values == pytest.approx([score.rank_score for score in ranked], rel=1e-5)
    assert "score curves (every episode)" in blueprint_names(outcome.recording)
    verify_recording(outcome.recording)  # `rerun rrd verify`: a whole, valid recording


def test_the_first_episodes_have_replays_opening_at_their_peak(written) -> None:
    _, _, outcome = written
    ranked = outcome.result.ranked
    assert list(outcome.replays) == [ranked[0].key, ranked[1].key]
    for score in ranked[:2]:
        assert properties(outcome.replays[score.key])["focus_frame"] == score.frame
    rows = csv_rows(outcome.table)
    assert rows[0]["open"].endswith(f"open {outcome.replays[ranked[0].key]}") and rows[2]["open"] == ""


def test_the_page_lists_every_episode_with_its_thumbnail(written) -> None:
    _, _, outcome = written
    page = outcome.page.read_text(encoding="utf-8")
    assert page.count("<tr>") == len(outcome.result.ranked) + 1
    assert page.count("data:image/jpeg;base64,") == len(outcome.result.ranked)
    assert 'href="triage.rrd"' in page and "robofailring open" in page


def test_a_second_triage_keeps_the_filled_rows_and_refuses_other_files(written, tmp_path: Path) -> None:
    config, _, outcome = written
    rows = csv_rows(outcome.table)
    rows[0] |= {"outcome": "failure", "symbol": "grasp_wp2"}
    with outcome.table.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    again = triage(config, replays=0)
    kept = {row["episode"]: row for row in csv.DictReader(again.table.open(encoding="utf-8"))}
    assert (kept[rows[0]["episode"]]["outcome"], kept[rows[0]["episode"]]["symbol"]) == (
        "failure",
        "grasp_wp2",
    )
    other = tmp_path / "out"
    other.mkdir()
    (other / "triage.csv").write_text("name,value\n")
    with pytest.raises(OutputError, match="not a labels CSV"):
        triage(TriageConfig(data=config.data, out=other), replays=0)
    assert sorted(p.name for p in other.iterdir()) == ["triage.csv"]
