"""The VLM client against a real local HTTP server: what it sends, retries, timeouts, bad bodies, the CLI."""

from __future__ import annotations

import base64
import json
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from ports import free_port
from synthetic import data_root_of, write_episode
from typer.testing import CliRunner
from vlm_server import ANSWER, chat_server, silent_server

from robofailring import (
    FailureDetector,
    FailureMemory,
    load_encoder,
    load_trajectory,
)
from robofailring.cli.verbs import app
from robofailring.data.images import read_image
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig, Scoring
from robofailring.explain.report import SYSTEM_PROMPT, TASKS, FailureReport, report_for
from robofailring.explain.vlm import (
    API_KEY_ENV,
    REDACTED,
    ChatCompletionsClient,
    VLMConfig,
    VLMError,
    ask_vlm,
    redact,
)
from robofailring.jobs.detect import DetectConfig, DetectResult, run_detect

runner = CliRunner()
SECRET = "sk-test-secret-4f9c1a"


@pytest.fixture(scope="module")
def episode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("episodes") / "pick_cube_grasp_wp2_episode9"
    return write_episode(folder, "pick_cube", "grasp_wp2", length=6, shift=2)


@pytest.fixture(scope="module")
def report(pixels_memory_dir: Path, aha_dataset: Path, episode: Path) -> FailureReport:
    memory = FailureMemory.load(pixels_memory_dir, trusted=[aha_dataset])
    trajectory = load_trajectory(episode)
    trace = FailureDetector(memory, load_encoder("pixels"), delta=-1.0, k=3).run(trajectory)
    found = report_for(trace, trajectory)
    assert found is not None and found.t_det == 0 and found.current_image is not None
    return found


def _config(url: str, **overrides: float) -> VLMConfig:
    settings = {"timeout_s": 5.0, "retries": 2, "backoff_s": 0.0} | overrides
    return VLMConfig(url=url, model="qwen2.5vl:7b", **settings)  # type: ignore[arg-type]


def _decode_data_url(url: str) -> np.ndarray:
    prefix = "data:image/jpeg;base64,"
    assert url.startswith(prefix), url[:40]
    data = base64.b64decode(url[len(prefix) :])
    assert data[:3] == b"\xff\xd8\xff"  # really a JPEG
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def test_the_request_is_appendix_b_with_three_images(
    report: FailureReport, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(API_KEY_ENV, "sk-test-secret")
    with chat_server() as server:
        answer = ask_vlm(report, _config(server.url))
    assert answer.ok and answer.answer == ANSWER and answer.model == "qwen2.5vl:7b"
    assert answer.latency_s is not None and answer.latency_s >= 0
    assert answer.to_dict() == {"model": "qwen2.5vl:7b", "answer": ANSWER, "latency_s": answer.latency_s}
    (exchange,) = server.received
    assert exchange.headers["Authorization"] == "Bearer sk-test-secret"
    body = exchange.body
    assert body["model"] == "qwen2.5vl:7b"
    messages = body["messages"]
    assert [m["role"] for m in messages] == ["system", "user", "user", "user", "user", "assistant"]
    assert messages[0]["content"] == SYSTEM_PROMPT and messages[4]["content"] == TASKS
    sent_report = json.loads(messages[1]["content"].split("\n", 1)[1])
    top = report.items[0]
    assert sent_report == {
        "current_task": "pick_cube",
        "failure": top.description,
        "view": top.view,
        "similarity_score": f"{top.similarity:.2f}",
    }
    parts = [part for m in messages if isinstance(m["content"], list) for part in m["content"]]
    urls = [part["image_url"]["url"] for part in parts if part["type"] == "image_url"]
    assert all(part["type"] in {"text", "image_url"} for part in parts)
    assert len(urls) == 3
    expected = [read_image(Path(p)) for p in (top.start_image, top.end_image, report.current_image or "")]
    for url, source in zip(urls, expected, strict=True):
        decoded = _decode_data_url(url)
        assert decoded.shape == source.shape
        # the right picture, in the right place (JPEG is lossy: a small mean error)
        assert float(np.abs(decoded.astype(int) - source.astype(int)).mean()) < 3.0
    assert float(np.abs(expected[0].astype(int) - expected[1].astype(int)).mean()) > 3.0  # start ≠ end
    assert "sk-test-secret" not in repr(ChatCompletionsClient(_config(server.url)))


def test_a_500_is_retried_then_reported(report: FailureReport) -> None:
    with chat_server(("status", 500)) as server:
        answer = ask_vlm(report, _config(server.url, retries=2))
    assert len(server.received) == 3  # first try + 2 retries
    assert answer.answer is None and answer.error is not None
    assert f"{server.url}/chat/completions" in answer.error and "HTTP 500" in answer.error
    assert answer.to_dict() == {"model": "qwen2.5vl:7b", "error": answer.error}


def test_a_500_then_an_answer_succeeds(report: FailureReport) -> None:
    with chat_server(("status", 503), ("ok", "second try")) as server:
        answer = ask_vlm(report, _config(server.url))
    assert answer.answer == "second try" and len(server.received) == 2


def test_a_4xx_is_not_retried(report: FailureReport) -> None:
    with chat_server(("status", 401)) as server:
        client = ChatCompletionsClient(_config(server.url))
        with pytest.raises(VLMError, match="refused the request: HTTP 401"):
            client.complete(report.vlm_messages())
    assert len(server.received) == 1


def test_a_timeout_is_retried_then_reported(report: FailureReport) -> None:
    with chat_server(("sleep", 1.5)) as server:
        answer = ask_vlm(report, _config(server.url, timeout_s=0.3, retries=1))
    assert len(server.received) == 2
    assert answer.error is not None and "did not answer within 0.3 s (2 attempts)" in answer.error


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (b'{"id": "x", "object": "chat.completion"}', r"without choices\[0\]\.message\.content"),
        (b'{"choices": []}', r"without choices\[0\]\.message\.content"),
        (b'{"choices": [{"message": {"role": "assistant", "content": ""}}]}', "empty"),
        (b"<html>gateway</html>", "not JSON"),
    ],
)
def test_a_malformed_body_says_what_is_missing(report: FailureReport, body: bytes, message: str) -> None:
    with chat_server(("raw", body)) as server, pytest.raises(VLMError, match=message) as raised:
        ChatCompletionsClient(_config(server.url)).complete(report.vlm_messages())
    assert f"{server.url}/chat/completions" in str(raised.value)
    assert len(server.received) == 1  # a bad body is not retried


def test_a_missing_report_image_is_an_error_naming_it(report: FailureReport, tmp_path: Path) -> None:
    gone = FailureReport.from_dict({**report.to_dict(), "current_image": str(tmp_path / "gone.png")})
    with chat_server() as server:
        answer = ask_vlm(gone, _config(server.url))
    assert answer.error is not None and "gone.png" in answer.error and not server.received


@pytest.mark.parametrize(
    ("echo", "shown"),
    [
        ("Authorization: Bearer sk-other-77", "Authorization: Bearer [redacted]"),
        ('{"authorization": "Bearer sk-other-77"}', '{"authorization": "Bearer [redacted]"}'),
        ("{'Authorization': 'Basic sk-other-77'}", "{'Authorization': 'Basic [redacted]'}"),
        ("api-key: sk-other-77", "api-key: [redacted]"),
        ('"x-api-key":"sk-other-77"', '"x-api-key":"[redacted]"'),
        ("api_key=sk-other-77; next", "api_key=[redacted]; next"),
    ],
)
def test_redact_hides_any_auth_header_value_and_the_key(echo: str, shown: str) -> None:
    assert redact(f"bad request ({echo}) for {SECRET}", SECRET) == f"bad request ({shown}) for {REDACTED}"
    assert redact("the gripper slipped", None) == "the gripper slipped"


def test_a_server_echoing_the_key_never_shows_it(report: FailureReport) -> None:
    """An error body echoing the request's headers, and an answer quoting the key: neither shows it."""
    with chat_server(("echo", 400), ("ok", f"Your key {SECRET} works.")) as server:
        client = ChatCompletionsClient(_config(server.url), api_key=SECRET)
        with pytest.raises(VLMError, match="refused the request: HTTP 400") as raised:
            client.complete(report.vlm_messages())
        answer = client.complete(report.vlm_messages())
    assert server.received[0].headers["Authorization"] == f"Bearer {SECRET}"  # the server did get it
    message = str(raised.value)
    assert SECRET not in message and "Authorization: Bearer [redacted]" in message
    assert raised.value.__cause__ is None and raised.value.__suppress_context__  # no traceback shows it
    assert answer == f"Your key {REDACTED} works."


def test_detect_json_never_shows_the_key_a_server_echoes(
    episode: Path, pixels_memory_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(API_KEY_ENV, SECRET)
    with chat_server(("echo", 400)) as server:
        code, found, stderr = _detect(
            episode, pixels_memory_dir, "--vlm-url", server.url, "--vlm-model", "llava"
        )
    assert code == 0, stderr
    assert server.received[0].headers["Authorization"] == f"Bearer {SECRET}"
    assert found["t_det"] == 0 and "HTTP 400" in found["vlm"]["error"] and REDACTED in found["vlm"]["error"]
    assert "HTTP 400" in stderr
    assert SECRET not in json.dumps(found) and SECRET not in stderr


def test_bad_settings() -> None:
    with pytest.raises(VLMError, match="must start with http"):
        VLMConfig(url="localhost:11434/v1", model="m")
    with pytest.raises(VLMError, match="model name"):
        VLMConfig(url="http://localhost:11434/v1", model="")


@pytest.mark.parametrize(
    ("url", "said"),
    [
        ("u:PW-hunter22@127.0.0.1:18089/v1", "'[redacted]@127.0.0.1:18089/v1' must start with http://"),
        ("http://u:PW-hunter22@[::1/v1", "'http://[redacted]@[::1/v1' is not a URL (Invalid IPv6 URL)"),
        ("http://u:PW-hunter22@host:port/v1", "is not a URL (Port could not be cast"),
    ],
)
def test_a_bad_vlm_url_is_one_error_line_before_any_work_without_its_password(
    episode: Path, pixels_memory_dir: Path, url: str, said: str
) -> None:
    """N1/N2: a URL without a scheme printed its password; one that does not parse was a traceback from
    `secrets`, after the detection ran."""
    code, found, stderr = _detect(episode, pixels_memory_dir, "--vlm-url", url, "--vlm-model", "llava")
    assert code == 2 and found == {}, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: VLM URL ") and said in lines[0], stderr
    assert "PW-hunter22" not in stderr and "Traceback" not in stderr


def _detect(episode: Path, pixels_memory_dir: Path, *extra: str) -> tuple[int, dict, str]:
    """`detect --json`, naming the folder of the memory's images (--data-root: they are not the episode's)."""
    result = runner.invoke(
        app,
        [
            "detect",
            str(episode),
            "--memory",
            str(pixels_memory_dir),
            "--data-root",
            data_root_of(pixels_memory_dir),
            "--delta",
            "-1",
            "--k",
            "3",
            "--json",
            *extra,
        ],
    )
    return result.exit_code, json.loads(result.stdout) if result.stdout.strip() else {}, result.stderr


def test_detect_asks_the_vlm_at_the_detection(episode: Path, pixels_memory_dir: Path) -> None:
    with chat_server() as server:
        code, found, stderr = _detect(
            episode, pixels_memory_dir, "--vlm-url", server.url, "--vlm-model", "llava"
        )
    assert code == 0, stderr
    assert found["t_det"] == 0 and found["vlm"]["model"] == "llava" and found["vlm"]["answer"] == ANSWER
    assert found["vlm"]["latency_s"] >= 0
    assert found["report"]["t_det"] == 0 and found["report"]["view"] == found["detected_view"]
    assert server.received[0].body["model"] == "llava"


def test_detect_keeps_the_detection_when_the_vlm_fails(
    episode: Path, pixels_memory_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    waits: list[float] = []  # the CLI's default backoff, recorded rather than slept (1 s + 2 s)
    defaults = ChatCompletionsClient.__init__.__kwdefaults__ or {}
    monkeypatch.setattr(ChatCompletionsClient.__init__, "__kwdefaults__", defaults | {"sleep": waits.append})
    with chat_server(("status", 502)) as server:
        code, found, stderr = _detect(
            episode, pixels_memory_dir, "--vlm-url", server.url, "--vlm-model", "llava"
        )
    assert code == 0
    assert (
        found["t_det"] == 0
        and set(found["vlm"]) == {"model", "error"}
        and "HTTP 502" in found["vlm"]["error"]
    )
    warnings = [line for line in stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and "HTTP 502" in warnings[0]
    assert len(server.received) == 3 and waits == [1.0, 2.0]


def test_detect_vlm_options_go_together(episode: Path, pixels_memory_dir: Path) -> None:
    code, _, stderr = _detect(episode, pixels_memory_dir, "--vlm-url", "http://127.0.0.1:9/v1")
    assert code == 2 and "--vlm-url and --vlm-model go together" in stderr


def test_no_server_is_an_error_naming_the_url(report: FailureReport) -> None:
    url = f"http://127.0.0.1:{free_port()}/v1"  # nobody listens on it
    answer = ask_vlm(report, _config(url))
    assert answer.error is not None and answer.error.startswith(f"cannot reach {url}/chat/completions")


def test_a_server_that_never_answers_is_abandoned_and_the_detection_kept(
    episode: Path, pixels_memory_dir: Path
) -> None:
    """A real socket that accepts and never writes: each attempt ends at the client's timeout."""
    done: list[DetectResult] = []
    with silent_server() as server:
        vlm = VLMConfig(url=server.url, model="m", timeout_s=0.5, retries=1, backoff_s=0.0)
        config = DetectConfig(
            data=DataSelection(episode),
            detector=DetectorConfig(
                memory=pixels_memory_dir,
                data_root=Path(data_root_of(pixels_memory_dir)),
                thresholds={"paper": -1.0},
                scoring=Scoring(k=3),
            ),
            vlm=vlm,
        )
        worker = threading.Thread(target=lambda: done.append(run_detect(config)), daemon=True)
        started = time.monotonic()
        worker.start()
        worker.join(timeout=vlm.timeout_s * (vlm.retries + 1) + 60)  # generous: a busy machine
        took = time.monotonic() - started
        accepted = len(server.accepted)
    assert not worker.is_alive() and done, f"detect still waiting on the VLM after {took:.0f} s"
    assert accepted == vlm.retries + 1  # every attempt reached the server and was kept waiting
    assert took >= vlm.timeout_s * (vlm.retries + 1)  # abandoned by the timeout, not refused
    found = done[0].to_dict()
    assert found["t_det"] == 0 and found["report"]["t_det"] == 0  # the detection is kept
    assert set(found["vlm"]) == {"model", "error"}
    assert "did not answer within 0.5 s (2 attempts)" in found["vlm"]["error"]
    assert any(note.startswith("warning: the VLM call failed") for note in done[0].notes)


def test_an_edited_report_never_sends_a_file_outside_its_roots(report: FailureReport, tmp_path: Path) -> None:
    """Issue 45 item 1: `explain` on a detection JSON whose images were edited to point at another file
    of yours sends nothing; --data-root names the folder they may come from instead."""
    private = tmp_path / "private.png"
    private.write_bytes(Path(report.items[0].start_image).read_bytes())
    edited = json.loads(report.to_json())
    edited["neighbors"][0]["start_image"] = str(private)
    source = tmp_path / "detection.json"
    source.write_text(json.dumps({"t_det": report.t_det, "report": edited}))
    from rfr_viz.jobs.explain import explain  # the job `robofailring explain` runs

    with chat_server() as server:
        found = explain(source, _config(server.url))
        assert server.received == []  # nothing reached the server
    assert found.answer.error is not None and f"report image {private} lies outside" in found.answer.error
    assert report.roots and all(Path(root).is_absolute() for root in report.roots)
    with chat_server() as server:
        trusted = explain(source, _config(server.url), data_root=tmp_path)  # the user names the folder
    assert (
        trusted.answer.error is not None and "lies outside" in trusted.answer.error
    )  # the others are not in it


# Issue 50 (security): a key as a Windows `.env` or a paste leaves it, credentials in --vlm-url, and a
# server echoing any of them in another case or cut short


def _ask(episode: Path, memory: Path, url: str) -> tuple[int, dict, str]:
    return _detect(episode, memory, "--vlm-url", url, "--vlm-model", "llava")


def test_a_key_ending_in_cr_lf_is_sent_stripped(
    episode: Path, pixels_memory_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(API_KEY_ENV, f"  {SECRET}\r\n")  # before: "Illegal header value b'Bearer sk-…\r'"
    with chat_server() as server:
        code, found, stderr = _ask(episode, pixels_memory_dir, server.url)
    assert code == 0 and found["vlm"] == {
        "model": "llava",
        "answer": ANSWER,
        "latency_s": found["vlm"]["latency_s"],
    }
    assert server.received[0].headers["Authorization"] == f"Bearer {SECRET}"
    assert SECRET not in stderr and SECRET not in json.dumps(found)


def test_a_non_ascii_key_is_refused_without_showing_it(
    episode: Path, pixels_memory_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(API_KEY_ENV, f"{SECRET}–é")  # a dash and a letter no HTTP header carries
    with chat_server() as server:
        code, found, stderr = _ask(episode, pixels_memory_dir, server.url)
    assert code == 2 and not found and not server.received  # refused before any work
    assert stderr.startswith("error: the VLM API key ($ROBOFAILRING_VLM_API_KEY) has a character")
    assert f"position {len(SECRET) + 1} of {len(SECRET) + 2}" in stderr
    assert "Traceback" not in stderr and SECRET not in stderr


def test_credentials_in_the_url_and_their_basic_token_are_never_shown(
    episode: Path, pixels_memory_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv(API_KEY_ENV, raising=False)
    password = "hunter2-pass"
    token = base64.b64encode(f"robot:{password}".encode()).decode()
    with chat_server(("echo", 400)) as server:
        url = server.url.replace("http://", f"http://robot:{password}@")
        code, found, stderr = _ask(episode, pixels_memory_dir, url)
    assert code == 0 and server.received[0].headers["Authorization"] == f"Basic {token}"
    said = json.dumps(found) + stderr
    assert "HTTP 400" in found["vlm"]["error"] and "Authorization: Basic [redacted]" in found["vlm"]["error"]
    assert password not in said and token not in said and "robot:" not in said
    unreachable = f"http://robot:{password}@127.0.0.1:{free_port()}/v1"
    code, found, stderr = _ask(episode, pixels_memory_dir, unreachable)
    assert code == 0 and found["vlm"]["error"].startswith("cannot reach http://[redacted]@127.0.0.1:")
    assert password not in json.dumps(found) + stderr


def test_an_echo_of_the_key_upper_cased_or_cut_is_hidden(
    episode: Path, pixels_memory_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(API_KEY_ENV, SECRET)
    echoed = f"A {SECRET.upper()} B {SECRET[:-2]} C {SECRET[2:].upper()} D"
    with chat_server(("ok", echoed)) as server:
        code, found, stderr = _ask(episode, pixels_memory_dir, server.url)
    assert code == 0 and found["vlm"]["answer"] == f"A {REDACTED} B {REDACTED} C {REDACTED} D"
    assert SECRET[2:-2].lower() not in (json.dumps(found) + stderr).lower()
    assert server.received[0].headers["Authorization"] == f"Bearer {SECRET}"


def test_redact_leaves_words_after_basic_or_bearer_alone() -> None:
    text = "a basic grasp; the bearer of the cube"
    assert redact(text, SECRET) == text
    assert (
        redact("token: Basic dTpQVw== and bearer sk-abc123")
        == f"token: Basic {REDACTED} and bearer {REDACTED}"
    )
