"""The VLM reasoning step (paper §3.4, Appendix B): the failure report sent to an OpenAI-compatible server.

Any server that speaks `POST {base_url}/chat/completions` works: vLLM, Ollama, LM Studio or a hosted
API. The report's images travel as base64 JPEG data URLs; the API key, when the server needs one,
comes from `ROBOFAILRING_VLM_API_KEY` and is sent only as a Bearer header (never printed or recorded, nor
the user and password of a URL `http://user:password@host/v1`).
"""

from __future__ import annotations

import base64
import os
import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final
from urllib.parse import unquote, urlsplit

from robofailring.data.frame_ref import reference_jpeg
from robofailring.errors import DataError, RoboFailRingError
from robofailring.explain.report import FailureReport, VLMClient
from robofailring.extras import needs_extra

if TYPE_CHECKING:
    import httpx

API_KEY_ENV: Final[str] = "ROBOFAILRING_VLM_API_KEY"
DEFAULT_TIMEOUT_S: Final[float] = 120.0  # a local VLM reading three images can take a while
DEFAULT_RETRIES: Final[int] = 2  # extra attempts after a timeout or a 5xx answer
DEFAULT_BACKOFF_S: Final[float] = 1.0  # wait before retry n: backoff × 2ⁿ
REDACTED: Final[str] = "[redacted]"
_MESSAGE_LIMIT: Final[int] = 400  # characters of an error message that quotes a server's body
# an auth header's value in any echo of it ("Authorization: Bearer …", JSON, a dict's repr, "api-key=…")
_SECRET_VALUE: Final[re.Pattern[str]] = re.compile(
    r"""((?:authorization|api[-_]?key)["']?\s*[:=]\s*["']?(?:(?:bearer|basic|token)\s+)?)"""
    r"[A-Za-z0-9\-._~+/]+=*",  # a token's characters (RFC 6750's b64token)
    re.IGNORECASE,
)
# a credential a server echoes without its header's name: a scheme, then a token (with a digit or `+/=_-`,
# so that "a basic grasp" stays as it is)
_AUTH_TOKEN: Final[re.Pattern[str]] = re.compile(
    r"\b((?:bearer|basic)\s+)(?=[A-Za-z0-9\-._~+/]*[0-9+/=_-])[A-Za-z0-9\-._~+/]{6,}=*", re.IGNORECASE
)
_USERINFO: Final[re.Pattern[str]] = re.compile(r"(?<=://)[^/\s@\"'<>]+@")  # `user:password@` of a URL
PARTIAL_ECHO: Final[int] = 8  # a secret's characters that, echoed in a row (any case), are hidden


class VLMError(RoboFailRingError):
    """The VLM server could not be reached, refused the request, or answered something unusable."""


class VLMCallError(VLMError):
    """A VLM call that a command depends on failed: an error of the environment (exit 1), not of the input."""

    exit_code = 1


@dataclass(frozen=True)
class VLMConfig:
    """Where to ask: an OpenAI-compatible server and the model it serves."""

    url: str  # base URL, e.g. http://localhost:11434/v1 (the client adds /chat/completions)
    model: str  # model name as the server knows it, e.g. qwen2.5vl:7b
    timeout_s: float = DEFAULT_TIMEOUT_S  # per attempt
    retries: int = DEFAULT_RETRIES  # extra attempts after a timeout or 5xx (never after a 4xx)
    backoff_s: float = DEFAULT_BACKOFF_S

    def __post_init__(self) -> None:
        if not self.url.startswith(("http://", "https://")):
            raise VLMError(f"VLM URL {redact_url(self.url)!r} must start with http:// or https://")
        try:  # parsed once here, where the option is read: not after the detections, in `secrets`
            parts = urlsplit(self.url)
            parts.port  # noqa: B018  (a port that is no number is a ValueError only when read)
        except ValueError as error:
            raise VLMError(f"VLM URL {redact_url(self.url)!r} is not a URL ({error})") from None
        if not parts.hostname:
            raise VLMError(f"VLM URL {redact_url(self.url)!r} names no host")
        if not self.model:
            raise VLMError("a VLM model name is needed (--vlm-model)")
        if self.retries < 0 or self.timeout_s <= 0:
            raise VLMError(
                f"VLM retries must be ≥ 0 and timeout > 0, got {self.retries} and {self.timeout_s}"
            )

    @property
    def endpoint(self) -> str:
        return f"{self.url.rstrip('/')}/chat/completions"

    @property
    def secrets(self) -> tuple[str, ...]:
        """The URL's password and the Basic token a client makes of its user and password (to hide)."""
        parts = urlsplit(self.url)
        if parts.username is None and parts.password is None:
            return ()
        user, password = unquote(parts.username or ""), unquote(parts.password or "")
        token = base64.b64encode(f"{user}:{password}".encode()).decode("ascii")
        return tuple(secret for secret in (password, token) if secret)

    def __repr__(self) -> str:  # never shows a password in the URL
        return f"VLMConfig(url={redact_url(self.url)!r}, model={self.model!r})"


def read_api_key(value: str | None = None) -> str | None:
    """The API key: `value`, else `$ROBOFAILRING_VLM_API_KEY`, its surrounding whitespace stripped (a line
    of a Windows `.env` ends in CR); None when empty. A key an HTTP header cannot carry (a non-ASCII or
    control character) is a VLMError that names the variable and the position, never the key."""
    key = (value if value is not None else os.environ.get(API_KEY_ENV, "")).strip()
    bad = next((at for at, char in enumerate(key) if not " " <= char <= "~"), None)
    if bad is not None:
        raise VLMError(
            f"the VLM API key (${API_KEY_ENV}) has a character an HTTP header cannot carry (non-ASCII or a "
            f"control character) at position {bad + 1} of {len(key)}: refused (the key is not shown)"
        )
    return key or None


@dataclass(frozen=True)
class VLMAnswer:
    """What the VLM said about one report, or why it said nothing."""

    model: str
    answer: str | None = None
    latency_s: float | None = None  # the whole call, retries included
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None

    def to_dict(self) -> dict[str, Any]:
        """`{model, answer, latency_s}`, or `{model, error}` when the call failed."""
        if self.error is not None:
            return {"model": self.model, "error": self.error}
        return {"model": self.model, "answer": self.answer, "latency_s": self.latency_s}

    def to_markdown(self) -> str:
        if self.error is not None:
            return f"## VLM answer ({self.model})\n\n_The VLM call failed: {self.error}_"
        return f"## VLM answer ({self.model}, {self.latency_s:.1f} s)\n\n{self.answer}"


def image_data_url(reference: str) -> str:
    """A report image as a `data:image/jpeg;base64,…` URL (JPEG files pass through unchanged)."""
    jpeg = reference_jpeg(reference, quality=90, what="report image", needed="; the VLM needs it")
    return "data:image/jpeg;base64," + base64.b64encode(jpeg).decode("ascii")


def openai_messages(messages: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The report's chat messages with every `{"type": "image", "path": …}` part as an `image_url` part."""
    converted = []
    for message in messages:
        content = message["content"]
        if isinstance(content, list):
            content = [
                {"type": "image_url", "image_url": {"url": image_data_url(part["path"])}}
                if part.get("type") == "image"
                else part
                for part in content
            ]
        converted.append({"role": message["role"], "content": content})
    return converted


def redact(text: str, *secrets: str | None) -> str:
    """`text` with every secret, any auth header's value or Bearer/Basic token and any URL's `user:password@`
    replaced by `[redacted]`: a server may echo them back, upper-cased or cut (any PARTIAL_ECHO characters
    of a secret in a row are hidden, in any case)."""
    text = _SECRET_VALUE.sub(lambda match: match.group(1) + REDACTED, text)
    text = _AUTH_TOKEN.sub(lambda match: match.group(1) + REDACTED, text)
    text = _USERINFO.sub(REDACTED + "@", text)
    for secret in secrets:
        if secret:
            text = _hide(text, secret)
    return text


def redact_url(url: str) -> str:
    """`url` as it may be printed: its `user:password@` hidden, with a scheme (`redact`) or without one
    (`u:pw@host/v1`, everything before the host's last `@`)."""
    shown = redact(url)
    if "://" not in shown:
        authority, slash, rest = shown.partition("/")
        if "@" in authority:
            shown = f"{REDACTED}@{authority.rpartition('@')[2]}{slash}{rest}"
    return shown


def _hide(text: str, secret: str) -> str:
    """`text` with `secret` hidden: every run of characters covered by a PARTIAL_ECHO-long piece of it (any
    case); a shorter secret where it stands alone (any case), not inside a word."""
    if len(secret) < PARTIAL_ECHO:
        alone = rf"(?<![A-Za-z0-9]){re.escape(secret)}(?![A-Za-z0-9])"
        return re.sub(alone, REDACTED, text, flags=re.IGNORECASE)
    pieces = {secret[at : at + PARTIAL_ECHO] for at in range(len(secret) - PARTIAL_ECHO + 1)}
    starts = re.compile(f"(?=({'|'.join(map(re.escape, sorted(pieces)))}))", re.IGNORECASE)
    covered = [False] * len(text)
    for match in starts.finditer(text):
        covered[match.start() : match.end(1)] = [True] * (match.end(1) - match.start())
    out, at = [], 0
    while at < len(text):
        end = at
        while end < len(text) and covered[end] == covered[at]:
            end += 1
        out.append(REDACTED if covered[at] else text[at:end])
        at = end
    return "".join(out)


def _one_line(text: str, limit: int = _MESSAGE_LIMIT) -> str:
    """An error message quoting a server: whitespace collapsed, cut to `limit` characters."""
    return " ".join(text.split())[:limit]


def _answer_text(body: Any, endpoint: str) -> str:
    """`choices[0].message.content` of a chat-completions body (text, or a list of text parts)."""
    try:
        content = body["choices"][0]["message"]["content"]
    except (KeyError, IndexError, TypeError) as error:
        keys = sorted(body) if isinstance(body, dict) else type(body).__name__
        raise VLMError(
            f"{endpoint} answered without choices[0].message.content (missing {error}; body keys: {keys})"
        ) from error
    if isinstance(content, list):
        content = "".join(part.get("text", "") for part in content if isinstance(part, dict))
    if not isinstance(content, str) or not content.strip():
        raise VLMError(f"{endpoint} answered with an empty choices[0].message.content")
    return content


class ChatCompletionsClient:
    """A `VLMClient` for OpenAI-compatible servers, with a timeout and bounded retries."""

    def __init__(
        self,
        config: VLMConfig,
        *,
        api_key: str | None = None,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.config = config
        self._key = read_api_key(api_key)  # stripped, and checked before anything is sent
        self._secrets = (self._key, *config.secrets)
        self._headers = {"Authorization": f"Bearer {self._key}"} if self._key else {}
        self._sleep = sleep

    def __repr__(self) -> str:  # never shows the key
        return f"ChatCompletionsClient(url={self.config.url!r}, model={self.config.model!r})"

    def complete(self, messages: list[dict[str, Any]]) -> str:
        """Send the conversation (report images as data URLs) and return the model's answer.

        Every text from the server, answer or error, is redacted here, the one place, before anyone sees it:
        a server that echoes the request would otherwise put the key into outputs and recordings.
        """
        try:
            return redact(self._exchange(messages), *self._secrets)
        except VLMError as error:  # not chained: the original message holds the unredacted text
            raise VLMError(_one_line(redact(str(error), *self._secrets))) from None

    def _exchange(self, messages: list[dict[str, Any]]) -> str:
        with needs_extra("vlm"):
            import httpx

        payload = {"model": self.config.model, "messages": openai_messages(messages)}
        endpoint = self.config.endpoint
        attempts = self.config.retries + 1
        with httpx.Client(timeout=self.config.timeout_s, headers=self._headers) as client:
            for attempt in range(attempts):
                last = attempt == attempts - 1
                try:
                    response = client.post(endpoint, json=payload)
                except httpx.TimeoutException as error:
                    if last:
                        raise VLMError(
                            f"{endpoint} did not answer within {self.config.timeout_s:g} s "
                            f"({attempts} attempts): {type(error).__name__}"
                        ) from error
                except (httpx.HTTPError, httpx.InvalidURL) as error:
                    raise VLMError(f"cannot reach {endpoint}: {error}") from error
                else:
                    if response.status_code < 400:
                        return self._parse(response, endpoint)
                    detail = f"HTTP {response.status_code} {response.reason_phrase}: {response.text}"
                    if response.status_code < 500:
                        raise VLMError(f"{endpoint} refused the request: {detail}")
                    if last:
                        raise VLMError(f"{endpoint} failed {attempts} times, last with {detail}")
                self._sleep(self.config.backoff_s * 2**attempt)
        raise AssertionError("unreachable: the last attempt returns or raises")

    @staticmethod
    def _parse(response: httpx.Response, endpoint: str) -> str:
        try:
            body = response.json()
        except ValueError as error:
            raise VLMError(
                f"{endpoint} answered HTTP {response.status_code} with a body that is not JSON: "
                f"{response.text!r}"
            ) from error
        return _answer_text(body, endpoint)


def ask_vlm(report: FailureReport, config: VLMConfig, *, client: VLMClient | None = None) -> VLMAnswer:
    """Ask the VLM about a report; a failed call becomes a `VLMAnswer` with `error` (never raises it).

    `client` is any `VLMClient` (default: a `ChatCompletionsClient` for `config`).
    """
    missing = report.missing_images()
    if missing:
        return VLMAnswer(
            model=config.model,
            error=f"not sent: {len(missing)} report image(s) not found (first: {missing[0]}); "
            "the VLM must see them; if the dataset moved, pass --data-root DIR",
        )
    outside = report.images_outside()
    if outside:
        return VLMAnswer(
            model=config.model,
            error=f"not sent: report image {outside[0]} lies outside the report's folders, those named for its "
            f"images ({', '.join(report.roots) or 'none named'}), once links are followed; pass --data-root DIR, "
            "the folder its images are in, if you trust it",
        )
    chat = client if client is not None else ChatCompletionsClient(config)
    started = time.perf_counter()
    try:
        answer = chat.complete(report.vlm_messages())
    except (VLMError, DataError) as error:
        return VLMAnswer(model=config.model, error=str(error))
    return VLMAnswer(model=config.model, answer=answer, latency_s=round(time.perf_counter() - started, 3))
