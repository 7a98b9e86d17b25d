"""A task with success runs only, as a user runs it: build-memory, calibrate, detect --json, replay;
the recording read back shows N_t against η, the nearest success frame, and says there is no failure neighbour."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rrd import columns, entity_paths, properties, rows, static_value
from synthetic import write_project_dataset
from typer.testing import CliRunner, Result

from rfr_viz.cli.app import app
from rfr_viz.paths import REPLAY
from rfr_viz.viewer.rrd import verify_recording
from robofailring import CachedEncoder, FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.detection.rules import NOVELTY

runner = CliRunner()


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("novelty-cli")
    data = write_project_dataset(root / "data", tasks=("pick_cube",), symbols=(), episodes=6, length=6)
    memory, cache = root / "memory", ["--cache-dir", str(root / "cache")]
    built = runner.invoke(app, ["build-memory", str(data), "--out", str(memory), "--split", "train", *cache])
    assert built.exit_code == 0, built.output
    calibrated = runner.invoke(
        app, ["calibrate", str(data), "--memory", str(memory), "--target-fpr", "0.4", *cache]
    )
    assert calibrated.exit_code == 0, calibrated.output
    assert "η = " in calibrated.output and "(novelty rule)" in calibrated.output
    return {"data": data, "memory": memory, "cache": root / "cache", "root": root}


def test_detect_json_is_judged_by_novelty_at_the_calibrated_eta(session: dict[str, Path]) -> None:
    eta = FailureMemory.load(session["memory"]).calibrated_threshold("novelty")
    assert eta is not None
    key = load_dataset(session["data"]).select(split="test")[0].key
    found = runner.invoke(
        app,
        [
            "detect",
            str(session["data"]),
            "--trajectory",
            key,
            "--memory",
            str(session["memory"]),
            "--json",
            "--cache-dir",
            str(session["cache"]),
        ],
    )
    assert found.exit_code == 0, found.output
    body = json.loads(found.output)
    assert body["score"] == "novelty" and body["threshold"] == eta and body["thresholds"]["novelty"] == eta
    view = next(iter(body["views"]))
    novelty, success = body["views"][view]["novelty"], body["views"][view]["success_similarity"]
    assert novelty == pytest.approx([1 - s for s in success], abs=2e-6)
    assert all(top is None for top in body["views"][view]["top_neighbor"])  # no failure to be near
    overridden = runner.invoke(
        app,
        [
            "detect",
            str(session["data"]),
            "--trajectory",
            key,
            "--memory",
            str(session["memory"]),
            "--eta",
            "0",
            "--cache-dir",
            str(session["cache"]),
        ],
    )
    assert overridden.exit_code == 0 and "rule novelty: N_t ≥ η = 0.000" in overridden.output
    assert "FAILURE detected at frame 0/" in overridden.output
    refused = runner.invoke(
        app,
        [
            "detect",
            str(session["data"]),
            "--trajectory",
            key,
            "--memory",
            str(session["memory"]),
            "--score",
            "paper",
            "--cache-dir",
            str(session["cache"]),
        ],
    )
    assert refused.exit_code == 2 and "the paper rule needs failure runs in the memory" in refused.output


def test_the_replay_shows_n_against_eta_and_the_nearest_success_frame(session: dict[str, Path]) -> None:
    trajectory = load_dataset(session["data"]).select(split="test")[0]
    out = session["root"] / "rec"
    replayed = runner.invoke(
        app,
        [
            "replay",
            str(session["data"]),
            "--memory",
            str(session["memory"]),
            "--out",
            str(out),
            "--trajectory",
            trajectory.key,
            "--eta",
            "0.0005",
            "--cache-dir",
            str(session["cache"]),
        ],
    )
    assert replayed.exit_code == 0, replayed.output
    (recording,) = out.glob("*.rrd")
    verify_recording(recording)
    memory = FailureMemory.load(session["memory"])
    detector = FailureDetector(
        memory, CachedEncoder(load_encoder("pixels"), cache_dir=session["cache"]), eta=0.0005
    )
    trace = detector.run(trajectory)
    assert trace.rule is NOVELTY and trace.t_det is not None
    props = properties(recording)
    assert (props["score"], props["threshold"], props["eta"]) == (
        "novelty",
        pytest.approx(0.0005),
        pytest.approx(0.0005),
    )
    assert props["failure_entries"] == 0 and props["memory_entries"] == 0 and props["t_det"] == trace.t_det
    paths = entity_paths(recording)
    for view in trace.views:
        assert (
            REPLAY.score(view, "paper") not in paths and REPLAY.score(view, "contrast") not in paths
        )  # no S⁻, no C
        logged = rows(recording, REPLAY.score(view, "novelty"), "Scalars:scalars")
        assert [frame for frame, _ in logged] == list(range(trace.length))
        np.testing.assert_allclose(
            [value[0] for _, value in logged], trace.scores_of(NOVELTY)[view], atol=1e-6
        )
        texts = rows(recording, REPLAY.nearest_success_info(view), "TextDocument:text")
        assert len(texts) == trace.length
        for t, text in texts:
            match = trace.nearest_success(view, t)
            assert (
                match is not None and match.run.episode in text[0] and f"frame **{match.frame}**" in text[0]
            )
        said = static_value(recording, REPLAY.neighbor(view, 0, "info"), "TextDocument:text")
        assert "No failure neighbours" in said[0] and "pick_cube" in said[0]
    eta = rows(recording, REPLAY.threshold("novelty"), "Scalars:scalars")
    assert len(eta) == trace.length and all(value[0] == pytest.approx(0.0005) for _, value in eta)
    assert REPLAY.threshold("contrast") not in paths and REPLAY.threshold("paper") not in paths
    assert static_value(recording, REPLAY.score(trace.views[0], "novelty"), "SeriesLines:names") == [
        f"{trace.views[0]} {NOVELTY.formula}"
    ]
    event = rows(recording, REPLAY.event, "TextLog:text")
    assert event[0][0] == trace.t_det and "(novelty rule): N_t = " in event[0][1][0]
    assert "no failure of this task in the memory; nearest success frame" in event[0][1][0]
    reports = rows(recording, REPLAY.report, "TextDocument:text")
    assert "Fired by the novelty rule" in reports[-1][1][0] and "Novelty: N = 1 − S⁺ = " in reports[-1][1][0]

    info = runner.invoke(app, ["memory-info", str(session["memory"])])
    assert (
        info.exit_code == 0 and "calibrated: novelty 0." in info.output and "entries     0 × " in info.output
    )


def test_live_streams_n_against_eta_and_says_there_is_no_failure_neighbour(
    session: dict[str, Path], tmp_path: Path
) -> None:
    from rfr_viz.recordings.live import LiveRecording
    from rfr_viz.recordings.live_target import LiveTarget

    memory = FailureMemory.load(session["memory"])
    detector = FailureDetector(memory, load_encoder("pixels"), eta=0.0005)
    trajectory = load_dataset(session["data"]).select(split="test")[0]
    frames = [{view: trajectory.views[view][t].load() for view in trajectory.views} for t in range(6)]
    saved = tmp_path / "live.rrd"
    with LiveRecording.open(
        detector, "pick_cube", views=list(trajectory.views), target=LiveTarget(save=saved)
    ) as live:
        stream = detector.session("pick_cube", sink=live)
        steps = [stream.step(images) for images in frames]
    assert all(step.rule is NOVELTY for step in steps) and live.fired_at == stream.fired_at is not None
    view = trajectory.views and next(iter(trajectory.views))
    found = rows(saved, REPLAY.score(view, "novelty"), "Scalars:scalars")
    np.testing.assert_allclose(
        [value[0] for _, value in found], [s.rule_scores["novelty"][view] for s in steps], atol=1e-6
    )
    assert len(rows(saved, REPLAY.threshold("novelty"), "Scalars:scalars")) == 6 and REPLAY.score(
        view, "paper"
    ) not in entity_paths(saved)
    said = static_value(saved, REPLAY.neighbor(view, 0, "info"), "TextDocument:text")
    assert "No failure neighbours" in said[0]
    event = rows(saved, REPLAY.event, "TextLog:text")
    assert (
        "(novelty rule): N_t = " in event[0][1][0]
        and "no failure of this task in the memory" in event[0][1][0]
    )


def test_watch_takes_eta_and_streams_what_detect_finds(session: dict[str, Path], tmp_path: Path) -> None:
    trajectory = load_dataset(session["data"]).select(split="test")[0]
    memory, cache, saved = str(session["memory"]), str(session["cache"]), tmp_path / "live.rrd"
    found = runner.invoke(
        app,
        [
            "detect",
            str(session["data"]),
            "--trajectory",
            trajectory.key,
            "--memory",
            memory,
            "--eta",
            "0.0005",
            "--json",
            "--cache-dir",
            cache,
        ],
    )
    assert found.exit_code == 0, found.output
    detected = json.loads(found.output)
    assert detected["score"] == "novelty" and detected["t_det"] is not None

    def watch(*options: str) -> Result:
        folder = session["data"] / trajectory.episode  # the episode folder, as a robot's run is given
        arguments = ["watch", str(folder), "--memory", memory, "--speed", "0", "--save", str(saved)]
        return runner.invoke(app, [*arguments, "--cache-dir", cache, *options])

    watched = watch("--eta", "0.0005")
    assert watched.exit_code == 0, watched.output
    assert f"FAILURE at frame {detected['t_det']} in view {detected['detected_view']}" in watched.output
    props = properties(saved)
    assert (props["score"], props["eta"], props["t_det"]) == ("novelty", 0.0005, detected["t_det"])
    assert props["threshold"] == 0.0005
    for view, scored in detected["views"].items():
        logged = rows(saved, REPLAY.score(view, "novelty"), "Scalars:scalars")
        np.testing.assert_allclose([value[0] for _, value in logged], scored["novelty"], atol=1e-6)
    assert {value[0] for _, value in rows(saved, REPLAY.threshold("novelty"), "Scalars:scalars")} == {0.0005}

    quiet = watch("--eta", "2")  # N_t ≤ 1 never reaches η = 2
    assert quiet.exit_code == 0 and "steps watched: no failure detected" in quiet.output, quiet.output
    assert properties(saved)["eta"] == 2.0
    refused = watch("--score", "paper")
    assert refused.exit_code == 2 and "the paper rule needs failure runs in the memory" in refused.output


@pytest.mark.slow  # an end-to-end run of every verb: the full lane
def test_evaluate_growth_charts_the_learning_curve(tmp_path: Path) -> None:
    data = write_project_dataset(tmp_path / "data", episodes=4)
    out = tmp_path / "eval"
    result = runner.invoke(
        app,
        [
            "evaluate",
            str(data),
            "--out",
            str(out),
            "--target-fpr",
            "0.5",
            "--growth",
            "0,1",
            "--cache-dir",
            str(tmp_path / "cache"),
        ],
    )
    assert result.exit_code == 0, result.output
    evaluation = json.loads((out / "evaluation.json").read_text(encoding="utf-8"))
    growth = evaluation["growth"]
    assert [(p["failures_per_task"], p["rule"]) for p in growth] == [
        (0, "novelty"),
        (1, "contrast"),
        (None, "contrast"),
    ]
    assert growth[-1]["recall"] == evaluation["rules"]["contrast"]["recall"]  # "all" is the evaluation itself
    one = json.loads((out / "growth-1" / "growth-1.json").read_text(encoding="utf-8"))
    assert growth[1]["recall"] == one["rules"]["contrast"]["recall"]
    assert len(FailureMemory.load(out / "growth-0" / "memory")) == 0
    assert "Learning curve: labelled failures per task" in (out / "report.html").read_text(encoding="utf-8")
    assert "| 0 | novelty | η = " in result.output
    labels = []
    for row in columns(out / "evaluation.rrd", "/eval/evaluation/growth/categories").get(
        "Points2D:labels", []
    ):
        labels += row or []
    assert labels == ["0 · novelty", "1 · contrast", "all · contrast"]
    refused = runner.invoke(
        app,
        [
            "evaluate",
            str(data),
            "--out",
            str(tmp_path / "e2"),
            "--growth",
            "0,x",
            "--cache-dir",
            str(tmp_path / "cache"),
        ],
    )
    assert refused.exit_code == 2 and "--growth takes whole numbers" in refused.output
