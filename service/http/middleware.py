"""ASGI middleware: the request body (framing, size limit, minimum rate and the worker's memory budget) and the
API key."""

from __future__ import annotations

import hmac
import json
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import anyio

from tracer.memory import release

Scope = dict[str, Any]
#: bodies from this size on leave enough garbage to be worth handing back to the OS at once
LARGE_BODY = 1 << 20
ASGIApp = Callable[..., Any]
#: refused bodies read and dropped at once by one worker (the event loop's work is bounded like the budget's); the
#: others are not read, and their clients may see the connection reset before the answer
DRAINS = 4


async def _send_json(
    send: Callable[..., Any], status: int, detail: str, headers: list | None = None, close: bool = False
) -> None:
    """A JSON error; ``close`` when the rest of the request will not be read (the connection cannot be reused)."""
    body = json.dumps({"detail": detail}).encode()
    extra = [(b"connection", b"close")] if close else []
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                *extra,
                *(headers or []),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})


class Framing:
    """A request with both ``Content-Length`` and ``Transfer-Encoding`` gets 400 and its connection is closed,
    before anything else answers it (RFC 9112 §6.1: such a message may be an attempt at request smuggling, and
    the server must close the connection after answering, so that nothing sent after its body is answered)."""

    def __init__(self, app: ASGIApp):
        self.app = app

    async def __call__(self, scope: Scope, receive: Callable[..., Any], send: Callable[..., Any]) -> None:
        if scope["type"] == "http":
            names = {name for name, _ in scope.get("headers", [])}
            if b"content-length" in names and b"transfer-encoding" in names:
                await _send_json(
                    send,
                    400,
                    "the request has both Content-Length and Transfer-Encoding headers; "
                    "send exactly one of them (RFC 9112 section 6.1)",
                    close=True,
                )
                return
        await self.app(scope, receive, send)


class BodyBudget:
    """The bytes of request bodies one worker holds at once, at most ``total``: each body takes its size before
    it is read and gives it back when its answer has gone out.  Bodies that do not fit wait in arrival order
    (first come, first served, so a large body is not starved by small ones) for at most ``wait`` seconds."""

    def __init__(self, total: int):
        self.total = total
        self.held = 0
        self._queue: deque[tuple[int, anyio.Event]] = deque()

    async def take(self, size: int, wait: float) -> bool:
        """Hold ``size`` bytes (at most ``total``: a body larger than the budget runs alone); False when they did
        not become free within ``wait`` seconds."""
        size = min(size, self.total)
        if not self._queue and self.held + size <= self.total:
            self.held += size
            return True
        entry = (size, anyio.Event())
        self._queue.append(entry)
        try:
            with anyio.move_on_after(wait):
                await entry[1].wait()
        except BaseException:  # cancelled from outside: hand back what was granted meanwhile, or leave the queue
            self._leave(entry)
            raise
        if entry[1].is_set():
            return True
        self._leave(entry)
        return False

    def give(self, size: int) -> None:
        self.held -= min(size, self.total)
        self._grant()

    def _leave(self, entry: tuple[int, anyio.Event]) -> None:
        if entry[1].is_set():
            self.give(entry[0])
        else:
            self._queue.remove(entry)
            self._grant()  # the queue's head may have changed

    def _grant(self) -> None:
        while self._queue and self.held + self._queue[0][0] <= self.total:
            size, event = self._queue.popleft()
            self.held += size
            event.set()


class BodyLimit:
    """Read the request body before the app sees it, and refuse what is malformed, too large or too slow, or what
    does not fit in the worker's memory budget.

    * A declared Content-Length over ``limit(path)`` bytes gets 413 at once; otherwise the body is read up to the
      limit (413 beyond it) and then replayed to the app.
    * Before anything of it is read, a body takes its declared length (a chunked body: the limit, the most it
      may be) from the worker's :class:`BodyBudget` of ``budget`` bytes, and holds it until its answer is sent; a
      body that finds no room within ``wait`` seconds gets 503 with ``Retry-After`` (:data:`DRAINS` of them at
      a time are read and dropped first).  So the request bodies one
      worker holds are bounded whatever the number of connections (those waiting are not read: TCP holds
      their senders back).
    * The body must have arrived ``grace`` seconds after it started plus one second per ``min_rate`` bytes (408
      otherwise), so a client trickling a byte a second is cut off.

    Each of these errors closes the connection: the rest of the request is not read.
    """

    def __init__(
        self,
        app: ASGIApp,
        limit: Callable[[str], int],
        grace: float = 10.0,
        min_rate: float = 65536,
        budget: int = 1 << 62,
        wait: float = 5.0,
        retry_after: int = 1,
    ):
        self.app = app
        self.limit = limit
        self.grace = grace
        self.min_rate = min_rate
        self.budget = BodyBudget(budget)
        self.wait = wait
        self.retry_after = retry_after
        self.draining = 0

    async def __call__(self, scope: Scope, receive: Callable[..., Any], send: Callable[..., Any]) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.limit(scope["path"])
        too_large = f"request body exceeds the limit max_body_bytes = {limit}"
        declared: int | None = None
        framed = False  # a Transfer-Encoding (chunked) body (never with a Content-Length: see Framing)
        for name, value in scope.get("headers", []):
            if name == b"content-length":
                try:
                    declared = int(value)
                except ValueError:
                    await _send_json(send, 400, "invalid Content-Length", close=True)
                    return
                if declared > limit:
                    await _send_json(
                        send,
                        413,
                        f"request body of {declared} bytes exceeds the limit max_body_bytes = {limit}",
                        close=True,
                    )
                    return
            elif name == b"transfer-encoding":
                framed = True
        size_taken = limit if framed else (declared or 0)
        if size_taken and not await self.budget.take(size_taken, self.wait):
            if self.draining < DRAINS:  # read and drop the body, so that the client can read the answer (no reset)
                self.draining += 1
                try:
                    await self._discard(receive, limit)
                finally:
                    self.draining -= 1
            await _send_json(
                send,
                503,
                f"this worker holds as many request bodies as it may "
                f"(max_buffered_bytes = {self.budget.total}); try again shortly",
                [(b"retry-after", str(self.retry_after).encode())],
                close=True,
            )
            return
        try:
            await self._read_and_run(scope, receive, send, limit, too_large)
        finally:
            if size_taken:
                self.budget.give(size_taken)

    async def _discard(self, receive: Callable[..., Any], limit: int) -> None:
        """Read and drop a refused body, up to its limit and at the body's minimum rate, holding none of it."""
        size, started = 0, time.monotonic()
        while size <= limit:
            with anyio.move_on_after(max(started + self.grace + size / self.min_rate - time.monotonic(), 0.0)):
                message = await receive()
                if message["type"] != "http.request" or not message.get("more_body", False):
                    return
                size += len(message.get("body", b""))
                continue
            return

    async def _read_and_run(
        self, scope: Scope, receive: Callable[..., Any], send: Callable[..., Any], limit: int, too_large: str
    ) -> None:
        chunks: deque[bytes] = deque()
        size = 0
        started = time.monotonic()
        while True:
            due = started + self.grace + size / self.min_rate
            with anyio.move_on_after(max(due - time.monotonic(), 0.0)) as waiting:
                message = await receive()
            if waiting.cancelled_caught:
                await _send_json(
                    send,
                    408,
                    f"the request body arrived too slowly (body_timeout = {self.grace:g} s, "
                    f"then body_min_rate = {self.min_rate:g} bytes per second)",
                    close=True,
                )
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
            if chunk:
                chunks.append(chunk)
            if not message.get("more_body", False):
                break

        ended = False

        async def replay() -> dict[str, Any]:
            """The body as it arrived, a chunk at a time: each is let go once the app has it (no joined copy)."""
            nonlocal ended
            if not ended:
                body = chunks.popleft() if chunks else b""
                ended = not chunks
                return {"type": "http.request", "body": body, "more_body": not ended}
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
            await _send_json(
                send,
                401,
                "missing or wrong API key (send exactly one of 'Authorization: Bearer KEY' and 'X-API-Key: KEY')",
                [(b"www-authenticate", b"Bearer")],
            )
            return
        await self.app(scope, receive, send)
