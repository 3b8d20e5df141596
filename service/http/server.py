"""Running the app under uvicorn: connections that cannot be held open for free.

* TCP_NODELAY on every connection.  A response goes out as two writes
  (headers, then body); on a kept-alive connection Nagle's algorithm holds the
  body back until the client acknowledges the headers, and a client that delays
  its acknowledgements adds about 40 ms to every request.
* A deadline for the request line and headers (``header_timeout``): uvicorn
  waits for them forever, so a client trickling a header byte a second would
  hold its connection open for as long as it likes.  (The body's deadline is in
  :class:`service.http.middleware.BodyLimit`; idle kept-alive connections are closed
  by uvicorn after ``keep_alive``; ``max_connections`` is uvicorn's
  ``limit_concurrency``.)
* With several workers, each connection goes to the worker holding the
  fewest (:mod:`service.http.balance`), so that two kept-alive clients do not
  share one worker's interpreter lock while another idles.
* The objects a worker holds once started (about 60k: FastAPI, Pydantic,
  NumPy and phongray's own) are frozen out of the garbage collector's rounds:
  a full collection, which runs on whichever thread allocated last and holds
  the interpreter meanwhile, would otherwise walk them all (40 ms here) while
  a large request is parsed, and stall the event loop with it.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import socket
import struct
from typing import Any

import h11
import uvicorn
from uvicorn.protocols.http.h11_impl import H11Protocol

from service.http import balance
from service.http.app import create_app
from service.settings import Settings


class Protocol(H11Protocol):
    header_timeout = Settings.from_env().header_timeout
    _headers_due: asyncio.TimerHandle | None = None

    def connection_made(self, transport: Any) -> None:
        sock = transport.get_extra_info("socket")
        if sock is not None and sock.family in (socket.AF_INET, socket.AF_INET6):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        super().connection_made(transport)
        self._await_headers()
        app = self.app

        def drop() -> None:
            # a reset, not a close: the kernel's send buffer is let go too (a close would keep delivering it, a
            # few MiB, to a client that does not read), and the client sees the connection end
            sock = transport.get_extra_info("socket")
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            transport.abort()

        async def with_abort(scope: Any, receive: Any, send: Any) -> None:
            # an answer's sender may drop a client that does not read (service.http.waiting.Streamed): the connection
            # is reset and what is queued for it let go, where close() would wait for the client
            scope["phongray.abort"] = drop
            await app(scope, receive, send)

        self.app = with_abort

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        if self.conn.their_state is not h11.IDLE:  # the request line and headers are in
            self._stop_waiting()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if not self.transport.is_closing():
            self._await_headers()  # of the next request on this connection

    def connection_lost(self, exc: Exception | None) -> None:
        self._stop_waiting()
        if balance.BOARD is not None:
            balance.BOARD.closed()
        super().connection_lost(exc)

    def _await_headers(self) -> None:
        self._stop_waiting()
        # up to 10 % later by connection, so that a burst of slow clients is not all closed in one loop turn
        spread = 1.0 + (id(self) // 16 % 101) / 1000.0
        self._headers_due = self.loop.call_later(self.header_timeout * spread, self._headers_late)

    def _stop_waiting(self) -> None:
        if self._headers_due is not None:
            self._headers_due.cancel()
            self._headers_due = None

    def _headers_late(self) -> None:
        self._headers_due = None
        if self.conn.their_state is h11.IDLE and not self.transport.is_closing():
            self.transport.close()


def worker_app() -> Any:
    """The app of one uvicorn worker, with what it holds after start-up frozen out of garbage collection."""
    app = create_app()
    gc.collect()  # (garbage made while starting is freed, not frozen)
    gc.freeze()
    return app


def serve(host: str, port: int, workers: int) -> None:
    """uvicorn with ``workers`` processes; with more than one, each connection goes to the worker that holds
    the fewest (:mod:`service.http.balance`)."""
    settings = Settings.from_env()
    with balance.board_for(workers) as board:
        uvicorn.run(
            "service.http.server:worker_app",
            factory=True,
            host=host,
            port=port,
            workers=workers,
            http=Protocol,
            log_level="info",
            timeout_keep_alive=settings.keep_alive,  # type: ignore[arg-type]
            limit_concurrency=settings.max_connections,
            loop="service.http.balance:balanced_loop" if board is not None else "auto",
        )
