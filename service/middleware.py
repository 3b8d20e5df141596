"""ASGI middleware: the request body (size limit and minimum rate) and the API key."""

from __future__ import annotations

import hmac
import json
import time
from collections.abc import Callable
from typing import Any

import anyio

from tracer.memory import release

Scope = dict[str, Any]
#: bodies from this size on leave enough garbage to be worth handing back to the OS at once
LARGE_BODY = 1 << 20
ASGIApp = Callable[..., Any]


async def _send_json(send: Callable[..., Any], status: int, detail: str, headers: list | None = None,
                     close: bool = False) -> None:
    """A JSON error; ``close`` when the rest of the request will not be read (the connection cannot be reused)."""
    body = json.dumps({"detail": detail}).encode()
    extra = [(b"connection", b"close")] if close else []
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                            *extra, *(headers or [])]})
    await send({"type": "http.response.body", "body": body})


class BodyLimit:
    """Read the request body before the app sees it, and refuse what is too large or too slow.

    A declared Content-Length over ``limit(path)`` bytes gets 413 at once; otherwise the body is read
    up to the limit (413 beyond it) and then replayed to the app, so memory stays bounded.  The body
    must have arrived ``grace`` seconds after it started plus one second per ``min_rate`` bytes (408
    otherwise), so a client trickling a byte a second is cut off.  Both errors close the connection.
    """

    def __init__(self, app: ASGIApp, limit: Callable[[str], int], grace: float = 10.0, min_rate: float = 65536):
        self.app = app
        self.limit = limit
        self.grace = grace
        self.min_rate = min_rate

    async def __call__(self, scope: Scope, receive: Callable[..., Any], send: Callable[..., Any]) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.limit(scope["path"])
        too_large = f"request body exceeds the limit max_body_bytes = {limit}"
        for name, value in scope.get("headers", []):
            if name == b"content-length":
                try:
                    declared = int(value)
                except ValueError:
                    await _send_json(send, 400, "invalid Content-Length", close=True)
                    return
                if declared > limit:
                    await _send_json(send, 413, f"request body of {declared} bytes exceeds the limit "
                                                f"max_body_bytes = {limit}", close=True)
                    return
        chunks: list[bytes] = []
        size = 0
        started = time.monotonic()
        while True:
            due = started + self.grace + size / self.min_rate
            with anyio.move_on_after(max(due - time.monotonic(), 0.0)) as waiting:
                message = await receive()
            if waiting.cancelled_caught:
                await _send_json(send, 408, f"the request body arrived too slowly (body_timeout = {self.grace:g} s, "
                                            f"then body_min_rate = {self.min_rate:g} bytes per second)", close=True)
                return
            if message["type"] != "http.request":
                return  # the client went away before sending its body
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > limit:
                await _send_json(send, 413, too_large, close=True)
                chunks.clear()
                await anyio.to_thread.run_sync(release)
                return
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        replayed = False

        async def replay() -> dict[str, Any]:
            nonlocal replayed
            if not replayed:
                replayed = True
                body = b"".join(chunks)
                chunks.clear()
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        try:
            await self.app(scope, replay, send)
        finally:
            if size > LARGE_BODY:  # a large body leaves its copies, parsed document and more behind: hand them back
                chunks.clear()
                await anyio.to_thread.run_sync(release)


def credential(headers: list[tuple[bytes, bytes]]) -> bytes | None:
    """The one credential of a request: ``Authorization: Bearer KEY`` (one space, nothing after the key)
    or ``X-API-Key: KEY``.  None when there is none, more than one, or another scheme."""
    given = [(name, value) for name, value in headers if name in (b"authorization", b"x-api-key")]
    if len(given) != 1:
        return None
    ((name, value),) = given
    if name == b"authorization":
        if value[:7].lower() != b"bearer ":
            return None
        value = value[7:]
    if not value or any(c <= 0x20 or c == 0x7F for c in value):
        return None
    return value


#: what needs no key: liveness, the playground and the API's documentation (pages without data, which take the
#: key from the user and send it with their requests)
OPEN = {"/healthz", "/", "/docs", "/redoc", "/openapi.json", "/favicon.ico"}


class ApiKey:
    """When a key is configured, every path but :data:`OPEN` needs exactly one credential with that key."""

    def __init__(self, app: ASGIApp, key: str):
        self.app = app
        self.key = key.encode()

    async def __call__(self, scope: Scope, receive: Callable[..., Any], send: Callable[..., Any]) -> None:
        path = scope.get("path", "")
        if scope["type"] != "http" or not self.key or path in OPEN or path.startswith("/docs-assets/"):
            await self.app(scope, receive, send)
            return
        given = credential(scope.get("headers", []))
        if given is None or not hmac.compare_digest(given, self.key):
            await _send_json(send, 401, "missing or wrong API key (send exactly one of 'Authorization: Bearer KEY' "
                                        "and 'X-API-Key: KEY')", [(b"www-authenticate", b"Bearer")])
            return
        await self.app(scope, receive, send)
