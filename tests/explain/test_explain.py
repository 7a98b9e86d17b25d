"""The VLM answer in replay recordings, and `explain` on a recording or on `detect --json` output."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from rrd import every_text, properties, rows
from synthetic import data_root_of, write_episode
from typer.testing import CliRunner
from vlm_server import ANSWER, chat_server

from rfr_viz.cli.app import app
from rfr_viz.paths import REPLAY
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.encoders.placement import EncoderPlacement
from robofailring.explain.vlm import API_KEY_ENV

runner = CliRunner()


@pytest.fixture(scope="module")
def episode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("episodes") / "push_cube_grasp_wp2_episode7"
    return write_episode(folder, "push_cube", "grasp_wp2", length=6, shift=1)


def _replay(episode: Path, pixels_memory_dir: Path, out: Path, delta: str, *vlm: str) -> Path:
    result = runner.invoke(
        app,
        [
            "replay",
            str(episode),
            "--memory",
            str(pixels_memory_dir),
            "--data-root",
            data_root_of(pixels_memory_dir),
            "--out",
            str(out),
            "--delta",
            delta,
            *vlm,
        ],
    )
    assert result.exit_code == 0, result.output
    (recording,) = out.glob("*.rrd")
    return recording


def test_replay_puts_the_answer_into_the_report_and_explain_asks_again(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    with chat_server(("ok", ANSWER), ("ok", "asked again")) as server:
        recording = _replay(
            episode,
            pixels_memory_dir,
            tmp_path / "rec",
            "-1",
            "--vlm-url",
            server.url,
            "--vlm-model",
            "llava",
        )
        found = properties(recording)
        assert found["t_det"] == 0 and found["vlm_model"] == "llava" and found["vlm_answer"] == ANSWER
        report = json.loads(found["report"])
        assert report["t_det"] == 0 and report["view"] == found["detected_view"] and report["neighbors"]
        reports = rows(recording, REPLAY.report, "TextDocument:text")
        assert [frame for frame, _ in reports] == [0, 0]  # the summary, then the report at t_det = 0
        text = reports[-1][1][0]
        assert "VLM answer (llava" in text and ANSWER in text and "Failure report" in text

        explained = runner.invoke(
            app,
            [
                *("explain", str(recording), "--vlm-url", server.url, "--vlm-model", "llava", "--json"),
                *("--data-root", str(episode.parent.parent)),  # the folder holding the memory's and the run's
            ],
        )
        assert explained.exit_code == 0, explained.output
        assert json.loads(explained.stdout)["answer"] == "asked again"
    assert len(server.received) == 2
    first, second = (exchange.body["messages"] for exchange in server.received)
    assert first == second  # the report read back from the recording is the one replay asked about


def test_explain_reads_detect_json(episode: Path, pixels_memory_dir: Path, tmp_path: Path) -> None:
    detected = runner.invoke(
        app,
        [
            *("detect", str(episode), "--memory", str(pixels_memory_dir), "--delta", "-1", "--json"),
            *("--data-root", data_root_of(pixels_memory_dir)),
        ],
    )
    assert detected.exit_code == 0, detected.output
    saved = tmp_path / "detect.json"
    saved.write_text(detected.stdout)
    vlm = ["--vlm-url", "http://127.0.0.1:9/v1", "--vlm-model", "m"]
    with chat_server() as server:
        vlm[1] = server.url
        # the images are neither beside the report nor named: nothing is sent, and it says where to look
        refused = runner.invoke(app, ["explain", str(saved), *vlm])
        explained = runner.invoke(
            app, ["explain", str(saved), *vlm, "--data-root", str(episode.parent.parent)]
        )
    assert refused.exit_code == 1 and "lies outside the report's folders" in refused.stderr, refused.output
    assert "(none named)" in refused.stderr  # not even the report's own folder: it may be a download
    assert explained.exit_code == 0, explained.output
    assert ANSWER in explained.stdout and "push_cube: failure at frame 0" in explained.stdout
    assert len(server.received) == 1  # the refused one sent nothing
    sent = server.received[0].body["messages"]
    assert json.loads(sent[1]["content"].split("\n", 1)[1])["current_task"] == "push_cube"


def test_a_failed_vlm_call_keeps_the_recording_and_says_so(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path
) -> None:
    with chat_server(("status", 400)) as server:
        result = runner.invoke(
            app,
            [
                "replay",
                str(episode),
                "--memory",
                str(pixels_memory_dir),
                "--data-root",
                data_root_of(pixels_memory_dir),
                "--out",
                str(tmp_path / "rec"),
                "--delta",
                "-1",
                "--vlm-url",
                server.url,
                "--vlm-model",
                "llava",
            ],
        )
        assert result.exit_code == 0, result.output
        assert "warning: the VLM call failed for push_cube/" in result.stderr and "HTTP 400" in result.stderr
        (recording,) = (tmp_path / "rec").glob("*.rrd")
        assert "HTTP 400" in properties(recording)["vlm_error"]
        explained = runner.invoke(
            app,
            [
                *("explain", str(recording), "--vlm-url", server.url, "--vlm-model", "m"),
                *("--data-root", str(episode.parent.parent)),
            ],
        )
    assert explained.exit_code == 1 and "HTTP 400" in explained.stderr


def test_a_replay_never_records_the_key_a_server_echoes(
    episode: Path, pixels_memory_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    secret = "sk-replay-secret-93d2"
    monkeypatch.setenv(API_KEY_ENV, secret)
    with chat_server(("echo", 400)) as server:
        result = runner.invoke(
            app,
            [
                *("replay", str(episode), "--memory", str(pixels_memory_dir), "--out", str(tmp_path / "rec")),
                *("--data-root", data_root_of(pixels_memory_dir)),
                *("--delta", "-1", "--vlm-url", server.url, "--vlm-model", "llava"),
            ],
        )
    assert result.exit_code == 0, result.output
    assert server.received[0].headers["Authorization"] == f"Bearer {secret}"
    (recording,) = (tmp_path / "rec").glob("*.rrd")
    assert "HTTP 400" in properties(recording)["vlm_error"] and "HTTP 400" in result.stderr
    assert "[redacted]" in properties(recording)["vlm_error"]
    assert secret not in result.output and secret not in every_text(recording)
    assert secret.encode() not in recording.read_bytes()


def test_explain_without_a_detection_or_a_report(pixels_memory_dir: Path, tmp_path: Path) -> None:
    success = write_episode(tmp_path / "push_cube_success_episode9", "push_cube", None, length=6)
    quiet = _replay(success, pixels_memory_dir, tmp_path / "quiet", "1.0")
    assert properties(quiet)["t_det"] == -1 and "report" not in properties(quiet)
    vlm = ["--vlm-url", "http://127.0.0.1:9/v1", "--vlm-model", "m"]
    result = runner.invoke(app, ["explain", str(quiet), *vlm])
    assert result.exit_code == 2 and "never fired" in result.stderr
    other = tmp_path / "other.json"
    other.write_text("[1, 2]")
    result = runner.invoke(app, ["explain", str(other), *vlm])
    assert result.exit_code == 2 and "does not hold a failure report" in result.stderr
    result = runner.invoke(app, ["explain", str(quiet)])
    assert result.exit_code == 2 and "explain needs --vlm-url and --vlm-model" in result.stderr


def test_review_puts_the_answer_into_each_false_alarm(tmp_path: Path) -> None:
    from synthetic import write_project_dataset

    from robofailring.evaluation.job import EvaluateConfig, run_evaluation
    from robofailring.evaluation.written import write_evaluation

    data = write_project_dataset(tmp_path / "data")
    result = run_evaluation(
        EvaluateConfig(
            data=DataSelection(data),
            threshold_policy=ThresholdPolicy(target_fpr=0.5),
            placement=EncoderPlacement(cache_dir=tmp_path / "cache"),
            out=tmp_path / "eval",
        )
    )
    json_path, _ = write_evaluation(result, tmp_path / "eval")
    # at δ = -1 every success run is a false alarm: review two of them
    evaluation = json.loads(json_path.read_text())
    successes = [t.key for t in result.scored if not t.is_failure][:2]
    evaluation["rules"]["paper"] |= {"threshold": -1.0, "false_alarms": successes}
    json_path.write_text(json.dumps(evaluation))
    alarms = evaluation["rules"]["paper"]["false_alarms"]
    assert len(alarms) == 2
    with chat_server() as server:
        reviewed = runner.invoke(
            app,
            [
                "review",
                str(json_path),
                "--data",
                str(data),
                "--score",
                "paper",
                "--out",
                str(tmp_path / "review"),
                "--cache-dir",
                str(tmp_path / "cache"),
                "--vlm-url",
                server.url,
                "--vlm-model",
                "llava",
            ],
        )
    assert reviewed.exit_code == 0, reviewed.output
    recordings = sorted((tmp_path / "review" / "false-alarms").glob("*.rrd"))
    assert len(recordings) == len(alarms) == len(server.received)
    for recording in recordings:
        found = properties(recording)
        assert found["vlm_answer"] == ANSWER and found["t_det"] == 0  # at δ = -1 the first frame fires
        text = rows(recording, REPLAY.report, "TextDocument:text")[-1][1][0]
        assert "VLM answer (llava" in text and ANSWER in text
