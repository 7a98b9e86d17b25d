"""A local OpenAI-compatible test server (127.0.0.1, a free port) that records what it was sent, and one that
never answers."""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

ANSWER = "The gripper closed beside the cube: re-grasp 2 cm to the left."


@dataclass
class Exchange:
    """One request as received: path, headers and the parsed JSON body."""

    path: str
    headers: dict[str, str]
    body: Any


@dataclass
class ChatServer:
    """Answers `POST /v1/chat/completions` following `replies`, one per request (the last repeats).

    A reply is ("ok", text), ("status", code), ("sleep", seconds), ("raw", body bytes) or ("echo", code):
    that status with the request's headers in the body, as a careless server or proxy sends them back.
    """

    url: str
    replies: list[tuple[str, Any]] = field(default_factory=lambda: [("ok", ANSWER)])
    received: list[Exchange] = field(default_factory=list)


@contextmanager
def chat_server(*replies: tuple[str, Any]) -> Iterator[ChatServer]:
    state = ChatServer(url="", replies=list(replies) or [("ok", ANSWER)])

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, format: str, *args: Any) -> None:  # quiet
            pass

        def _send(self, code: int, body: bytes, content_type: str = "application/json") -> None:
            self.send_response(code)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def do_POST(self) -> None:
            length = int(self.headers.get("Content-Length", "0"))
            raw = self.rfile.read(length)
            if self.path != "/v1/chat/completions":
                self._send(404, b'{"error": "not found"}')
                return
            index = len(state.received)
            state.received.append(Exchange(self.path, dict(self.headers.items()), json.loads(raw)))
            kind, value = state.replies[min(index, len(state.replies) - 1)]
            if kind == "sleep":
                time.sleep(value)
                kind, value = "ok", ANSWER
            if kind == "status":
                self._send(value, b'{"error": {"message": "the model is overloaded"}}')
            elif kind == "echo":
                headers = "\n".join(f"{name}: {text}" for name, text in self.headers.items())
                echoed = {"error": {"message": "bad request", "headers": dict(self.headers.items())}}
                self._send(value, f"{headers}\n\n{json.dumps(echoed)}".encode(), "text/plain")
            elif kind == "raw":
                self._send(200, value)
            else:
                body = {
                    "id": "x",
                    "object": "chat.completion",
                    "choices": [{"index": 0, "message": {"role": "assistant", "content": value}}],
                }
                self._send(200, json.dumps(body).encode())

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    server.daemon_threads = True
    # shutdown() waits for the serve loop's next poll: 0.5 s by default, on every test that starts one
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.02}, daemon=True)
    thread.start()
    state.url = f"http://127.0.0.1:{server.server_address[1]}/v1"
    try:
        yield state
    finally:
        server.shutdown()
        server.server_close()


@dataclass
class SilentServer:
    """A listening socket that accepts every connection and never reads or writes a byte."""

    url: str
    accepted: list[socket.socket] = field(default_factory=list)


@contextmanager
def silent_server() -> Iterator[SilentServer]:
    """A VLM endpoint that takes the connection and never answers (a hung server, a stuck proxy)."""
    listener = socket.create_server(("127.0.0.1", 0))
    state = SilentServer(url=f"http://127.0.0.1:{listener.getsockname()[1]}/v1")
    stop = threading.Event()

    def accept() -> None:
        listener.settimeout(0.1)
        while not stop.is_set():
            try:
                connection, _ = listener.accept()
            except TimeoutError:
                continue
            except OSError:  # closed under us at the end
                return
            state.accepted.append(connection)  # held open, silent, until the end

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield state
    finally:
        stop.set()
        thread.join(timeout=5)
        for connection in state.accepted:
            connection.close()
        listener.close()
