"""What every request passes before the application sees it, in this order:

1. its Host is one of the service's names (a DNS-rebinding page cannot read the API),
   and a WebSocket's Origin, when a browser sends one, is the page's own (same host and
   port as the Host); no response may be framed by another page (clickjacking);
2. a request that changes state carries the bearer token (checked before any byte of its
   body is read, so an unauthenticated client cannot make the service parse anything);
3. its body is at most `max_bytes` (413, whether announced or chunked) and arrives within
   `body_timeout_s` (408: a slow client cannot hold a connection for ever);
4. a JSON body has only finite numbers and well-formed strings (422 naming the field:
   NaN, Infinity, a number too large for a float such as 1e400, and lone surrogates are
   valid to Python's parser but poison a mission and cannot be echoed back as JSON), and
   is nested at most `MAX_JSON_DEPTH` deep (400: deeper has no use here, and ~1,000 deep
   overflows the parser's recursion);
5. a request that cannot change state (GET, HEAD, OPTIONS) has its body read, within the
   same bounds, and dropped unparsed: nothing the service answers depends on one.

Then the body, read once, is handed to the application unchanged.
"""

from __future__ import annotations

import asyncio
import json
import math
import re
from collections.abc import Iterator
from typing import Any

import numpy as np
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from gcs.service.api.auth import TokenRefused, check_bearer

MUTATING = frozenset({"POST", "PUT", "PATCH", "DELETE"})
MAX_JSON_DEPTH = 32
JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
OPENING, CLOSING = np.frombuffer(b"[{", dtype=np.uint8), np.frombuffer(b"]}", dtype=np.uint8)
Path = tuple[str | int, ...]


class Refusal(Exception):
    def __init__(self, status: int, detail: Any, headers: dict[str, str] | None = None) -> None:
        self.status, self.detail, self.headers = status, detail, headers or {}


class RequestGuard:
    def __init__(
        self,
        app: ASGIApp,
        *,
        token: Any,
        hosts: frozenset[str],
        max_bytes: int,
        body_timeout_s: float,
    ) -> None:
        self.app, self.token, self.hosts = app, token, hosts
        self.max_bytes, self.body_timeout_s = max_bytes, body_timeout_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        try:
            self._check_host(headers)
            if scope["type"] == "websocket":
                self._check_origin(headers)
                await self.app(scope, receive, send)
                return
            if scope["method"] in MUTATING:
                self._check_token(headers)
            body = await self._read_body(headers, receive)
            if scope["method"] not in MUTATING:
                body = b""  # dropped unparsed
            elif body and "json" in headers.get("content-type", "json"):
                check_json(body)
        except Refusal as refusal:
            await _refuse(scope, send, refusal)
            return
        await self.app(scope, _replay(body, receive), _not_framed(send))

    def _check_host(self, headers: dict[str, str]) -> None:
        host = _host_name(headers.get("host", ""))
        if host not in self.hosts:
            known = ", ".join(sorted(self.hosts))
            raise Refusal(400, f"unknown host {host!r}: this service answers to {known}")

    def _check_origin(self, headers: dict[str, str]) -> None:
        """A browser's WebSocket comes from a page of this service: its Origin names the
        same host and port as the request's Host (another local web app, on another
        port, is another origin)."""
        origin = headers.get("origin")
        if origin is None:
            return  # not a browser: nothing to rebind
        scheme, _, authority = origin.partition("://")
        if scheme not in ("http", "https") or _authority(authority) != _authority(
            headers.get("host", "")
        ):
            raise Refusal(403, f"WebSocket from origin {origin!r} refused")

    def _check_token(self, headers: dict[str, str]) -> None:
        try:
            check_bearer(headers.get("authorization"), self.token())
        except TokenRefused as refused:
            raise Refusal(refused.status_code, refused.detail, refused.headers) from None

    async def _read_body(self, headers: dict[str, str], receive: Receive) -> bytes:
        declared = headers.get("content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
            raise Refusal(413, f"request body larger than {self.max_bytes} bytes")
        chunks: list[bytes] = []
        size = 0
        try:
            async with asyncio.timeout(self.body_timeout_s):
                while True:
                    message = await receive()
                    if message["type"] != "http.request":
                        break
                    chunk = message.get("body", b"")
                    size += len(chunk)
                    if size > self.max_bytes:
                        raise Refusal(413, f"request body larger than {self.max_bytes} bytes")
                    chunks.append(chunk)
                    if not message.get("more_body", False):
                        break
        except TimeoutError:
            raise Refusal(
                408, f"the request body did not arrive within {self.body_timeout_s:g} s"
            ) from None
        return b"".join(chunks)


def check_json(body: bytes) -> None:
    """422 for NaN, Infinity or a lone surrogate anywhere in a JSON body, naming where.
    (Malformed JSON is left to the application, which says where it breaks.)"""
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise Refusal(400, f"the body is not UTF-8: {exc}") from None
    _check_depth(text)
    try:
        document = json.loads(text, parse_constant=_refuse_constant, parse_float=_finite)
    except _NonFinite as exc:
        raise Refusal(422, [_problem(("body",), f"{exc} is not a finite number")]) from None
    except ValueError:
        return
    for path, bad in _bad_values(document, ("body",)):
        raise Refusal(422, [_problem(path, bad)])


class _NonFinite(ValueError):
    pass


def _refuse_constant(name: str) -> None:
    raise _NonFinite(name)


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):  # 1e400: a literal too large for a float
        raise _NonFinite(text)
    return value


def _check_depth(text: str) -> None:
    """400 for arrays and objects nested deeper than MAX_JSON_DEPTH, counted before
    parsing (strings left out), so that the parser never recurses far."""
    brackets = np.frombuffer(JSON_STRING.sub("", text).encode(), dtype=np.uint8)
    step = np.isin(brackets, OPENING).astype(np.int64) - np.isin(brackets, CLOSING)
    if step.size and int(np.cumsum(step).max()) > MAX_JSON_DEPTH:
        raise Refusal(400, f"the JSON body is nested deeper than {MAX_JSON_DEPTH} levels")


def _bad_values(value: Any, path: Path) -> Iterator[tuple[Path, str]]:
    if isinstance(value, str):
        if not _encodable(value):
            yield path, "a string with a lone surrogate (not valid Unicode text)"
    elif isinstance(value, dict):
        for key, item in value.items():
            if not _encodable(key):
                yield path, "a key with a lone surrogate (not valid Unicode text)"
            yield from _bad_values(item, (*path, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from _bad_values(item, (*path, index))


def _encodable(text: str) -> bool:
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _problem(path: Path, message: str) -> dict[str, Any]:
    return {"loc": list(path), "msg": message, "type": "value_error"}


HOST = re.compile(r"(?:\[(?P<v6>[0-9a-f:.]+)\]|(?P<name>[^:\[\]/@\s]+))(?::(?P<port>\d{1,5}))?")


def _authority(text: str) -> tuple[str, str] | None:
    """`127.0.0.1:8000` -> ("127.0.0.1", "8000"), `[::1]` -> ("::1", ""), lower case;
    None for anything else (`[::1]evil.example`, a path, user info)."""
    match = HOST.fullmatch(text.strip().lower())
    if match is None:
        return None
    return match["v6"] or match["name"], match["port"] or ""


def _host_name(host: str) -> str:
    authority = _authority(host)
    return authority[0] if authority else ""


def _not_framed(send: Send) -> Send:
    """Every response refuses to be shown in another page's frame (the console's own CSP
    says so too; the API docs have none)."""

    async def guarded(message: Message) -> None:
        if message["type"] == "http.response.start":
            headers = list(message.get("headers", []))
            names = {name.lower() for name, _ in headers}
            headers.append((b"x-frame-options", b"DENY"))
            if b"content-security-policy" not in names:
                headers.append((b"content-security-policy", b"frame-ancestors 'none'"))
            message = {**message, "headers": headers}
        await send(message)

    return guarded


def _replay(body: bytes, receive: Receive) -> Receive:
    sent = False

    async def replay() -> Message:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()  # then the client's disconnect, when it comes

    return replay


async def _refuse(scope: Scope, send: Send, refusal: Refusal) -> None:
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 4000 + refusal.status})
        return
    body = json.dumps({"detail": refusal.detail}).encode()
    headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
        *((k.lower().encode(), v.encode()) for k, v in refusal.headers.items()),
    ]
    await send({"type": "http.response.start", "status": refusal.status, "headers": headers})
    await send({"type": "http.response.body", "body": body})
