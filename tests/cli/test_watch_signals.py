"""`watch` with the robot's signals, read back (issue 50's follow-ups): an alarm of the signals judged alone is
recorded without a camera (its instant, the report, the signals' nearest failure), and a view judged by a band
of its own (fusion per-modality) has its own threshold line live, as a replay draws it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from fault_helpers import cli
from rrd import properties, rows, static_value
from synthetic import write_project_dataset

from rfr_viz.paths import REPLAY
from robofailring.explain.report import NO_FAILURES
from robofailring.memory.signals.modality import SIGNALS_VIEW

EPISODE = "pick_cube_grasp_wp2_episode1"


def _data(root: Path, episodes: int) -> Path:
    return write_project_dataset(
        root, tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=episodes, length=8, signals=True
    )


def test_an_alarm_of_the_signals_alone_is_recorded_with_their_nearest_failure(
    cache: list[str], tmp_path: Path
) -> None:
    data = _data(tmp_path / "data", 6)
    memory, saved = tmp_path / "memory", tmp_path / "live.rrd"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    judging = ["--memory", memory, "--gamma", "0.05", "--modality", "signals", *cache]
    watched = cli("watch", data / EPISODE, *judging, "--speed", "0", "--save", saved)
    assert watched.exit_code == 0, watched.output  # was an AssertionError at the first alarm: no camera
    found = cli("detect", data, "--trajectory", EPISODE, "--json", *judging)
    assert found.exit_code == 0, found.output
    expected = json.loads(found.stdout)
    t_det = expected["t_det"]
    assert t_det is not None and expected["detected_view"] == SIGNALS_VIEW
    assert f"FAILURE at frame {t_det} in view {SIGNALS_VIEW}" in watched.stdout

    recorded = properties(saved)
    assert recorded["t_det"] == t_det and recorded["detected_view"] == SIGNALS_VIEW
    report = json.loads(recorded["report"])
    assert report["view"] == SIGNALS_VIEW and report["t_det"] == t_det and report["neighbors"] == []
    episode, symbol, frame = expected["signals"]["at_t_det"]["nearest_failure"]
    nearest = f"nearest failure: {episode}, `{symbol}`, frame {frame}"
    assert nearest in report["signals"]
    [(at, [event])] = rows(saved, REPLAY.event, "TextLog:text")
    assert at == t_det and nearest in event and "no failure of this task" not in event
    [(at, [document])] = [row for row in rows(saved, REPLAY.report, "TextDocument:text") if row[0] == t_det]
    assert nearest in document and NO_FAILURES not in document  # not "success runs only"


def test_watch_draws_a_views_own_threshold_line_as_the_replay_does(cache: list[str], tmp_path: Path) -> None:
    data = _data(tmp_path / "data", 24)  # 12 calibration successes: enough for a band (MIN_BAND_RUNS)
    memory = tmp_path / "memory"
    assert cli("build-memory", data, "--out", memory, "--split", "train", *cache).exit_code == 0
    calibrated = cli(
        "calibrate", data, "--memory", memory, "--target-fpr", "0.1", "--fusion", "per-modality", *cache
    )
    assert calibrated.exit_code == 0, calibrated.output
    live = tmp_path / "live.rrd"
    watched = cli("watch", data / EPISODE, "--memory", memory, "--speed", "0", "--save", live, *cache)
    assert watched.exit_code == 0, watched.output
    replayed = cli(
        "replay",
        data,
        "--memory",
        memory,
        "--trajectory",
        f"pick_cube/{EPISODE}",
        "--out",
        tmp_path / "r",
        *cache,
    )
    assert replayed.exit_code == 0, replayed.output
    [replay] = (tmp_path / "r").glob("*.rrd")

    own = REPLAY.view_threshold("contrast", SIGNALS_VIEW)
    expected = rows(replay, own, "Scalars:scalars")
    assert [frame for frame, _ in expected] == list(range(8))
    logged = rows(live, own, "Scalars:scalars")  # was absent: live drew the cameras' line only
    assert [frame for frame, _ in logged] == list(range(8))
    np.testing.assert_allclose([v[0] for _, v in logged], [v[0] for _, v in expected], atol=1e-6)
    cameras = rows(live, REPLAY.threshold("contrast"), "Scalars:scalars")
    assert not np.allclose([v[0] for _, v in cameras], [v[0] for _, v in logged])  # not the cameras' line
    np.testing.assert_allclose(
        [v[0] for _, v in cameras],
        [v[0] for _, v in rows(replay, REPLAY.threshold("contrast"), "Scalars:scalars")],
        atol=1e-6,
    )
    assert static_value(live, own, "SeriesLines:names") == static_value(replay, own, "SeriesLines:names")
