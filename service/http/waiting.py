"""Waiting on work without blocking the event loop: one render shared by every request for its scene, work on
a pool thread that stops once its client has left, and every answer of an image's bytes (a render, a pass, a
heat-map) priced against the worker's answers and streamed to a client that must read it."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, TypeVar

import anyio
from fastapi import Request, Response

from service.admission.limits import LimitError
from service.http.problems import HTTPProblem, unavailable
from service.render.passes import PassFile
from service.work.jobs import AnswersFull, Busy, ClusterDown, Job, RenderService, TooSlow
from tracer import ImageTooLarge, RenderCancelled

T = TypeVar("T")
#: seconds between two looks at whether a waiting client is still there (each look is a turn of the event loop,
#: and a hundred waiters look at once)
DISCONNECT_POLL = 0.25


class _Flight:
    """One render in progress, shared by every request for the same scene: they wait on it without a thread."""

    def __init__(self) -> None:
        self.done = anyio.Event()
        self.result: bytes | None = None
        self.failure: Exception | None = None
        self.waiting = 0  # requests still interested; the render stops when none is


async def rendered(request: Request, job: Job) -> bytes:  # noqa: C901 (the outcomes of a shared flight)
    """Render (or fetch) off the event loop; stop rendering once every client that wants it has gone."""
    service: RenderService = request.app.state.service
    cached = service.cache.get(job.key)
    if cached is not None:
        return cached
    flights: dict[str, _Flight] = request.app.state.flights
    flight = flights.get(job.key)
    leader = flight is None
    if flight is None:
        flight = flights[job.key] = _Flight()
    flight.waiting += 1
    gone = anyio.Event()
    waiting = anyio.CancelScope()  # a follower stops waiting when its client goes; the leader waits for its thread

    async def watch() -> None:
        while not gone.is_set() and not flight.done.is_set():
            if await request.is_disconnected():
                gone.set()
                flight.waiting -= 1
                waiting.cancel()
                return
            await anyio.sleep(DISCONNECT_POLL)

    async with anyio.create_task_group() as tasks:
        tasks.start_soon(watch)
        if leader:
            try:
                flight.result = await anyio.to_thread.run_sync(service.png, job, lambda: flight.waiting <= 0)
            except Exception as exc:  # shared with every waiter, re-raised below outside the task group
                flight.failure = exc
            finally:
                flights.pop(job.key, None)
                flight.done.set()
        else:
            with waiting:
                await flight.done.wait()
        tasks.cancel_scope.cancel()
    if not gone.is_set():
        flight.waiting -= 1
    if not gone.is_set() and isinstance(flight.failure, RenderCancelled):
        # the flight stopped when every client waiting on it had left, as this one joined it: render again
        return await rendered(request, job)
    failure = RenderCancelled("client closed the request") if gone.is_set() else flight.failure
    result = flight.result
    try:
        if failure is not None:
            raise failure
    except (Busy, TooSlow, ClusterDown) as exc:
        raise unavailable(exc, service) from None
    except RenderCancelled:
        raise HTTPProblem(499, "client closed the request") from None
    except ImageTooLarge as exc:  # only when the service's own limits are set above the renderer's
        raise HTTPProblem(422, str(exc)) from None
    except LimitError as exc:  # the render outgrew its budget
        raise HTTPProblem(exc.status, str(exc)) from None
    assert result is not None
    return result


class Gone(Exception):
    """The client left: nobody reads the answer."""


async def watched(request: Request, work: Callable[[Callable[[], bool]], T], limiter: Any) -> T:
    """``work(gone)`` on a pool thread (of ``limiter``), where ``gone()`` turns true once the client has left,
    looked at every :data:`DISCONNECT_POLL` seconds: the work polls it and stops (a 499, which nobody reads)."""
    left = threading.Event()

    async def watch() -> None:
        while not await request.is_disconnected():
            await anyio.sleep(DISCONNECT_POLL)
        left.set()

    failure: BaseException | None = None
    async with anyio.create_task_group() as tasks:
        tasks.start_soon(watch)
        try:
            result = await anyio.to_thread.run_sync(work, left.is_set, limiter=limiter)
        except Exception as exc:  # re-raised below, outside the task group (which would wrap it in a group)
            failure = exc
        tasks.cancel_scope.cancel()
    if isinstance(failure, RenderCancelled) and left.is_set():
        raise HTTPProblem(499, "client closed the request") from None
    if failure is not None:
        raise failure
    return result


def whole(
    service: RenderService, data: bytes, media: str, what: str, headers: dict[str, str] | None = None
) -> Response:
    """An answer made whole beforehand (a render's PNG, a heat-map; ``what`` it is, in words) served as a pass
    is (:func:`streamed`), priced at its size against ``max_answer_bytes``: 503 with Retry-After when it does not
    fit now, 422 when it never would."""
    try:
        held = service.answers.hold(len(data), what)
    except AnswersFull as exc:
        raise unavailable(exc, service) from None
    except LimitError as exc:
        raise HTTPProblem(exc.status, str(exc)) from None
    return streamed(service, PassFile(b"", data, media), held, headers)


def streamed(service: RenderService, file: PassFile, held: int, headers: dict[str, str] | None = None) -> Response:
    """Every answer of a render's bytes, a pass's or a whole one's: ``held`` bytes of the worker's answers
    (``max_answer_bytes``, taken by the caller) until it is over, sent a chunk at a time within
    ``send_timeout`` (:class:`Streamed`), with ``headers`` besides its own."""
    return Streamed(file, service.settings.send_timeout, lambda: service.answers.give(held), headers)


class Streamed(Response):
    """A large answer sent a chunk at a time (:meth:`service.render.passes.PassFile.chunks`), never joined: each chunk
    must be taken by the client within ``timeout`` seconds (``send_timeout``), else the connection is dropped;
    either way ``done()`` runs once it is over (the answer's memory is let go and its budget given back)."""

    def __init__(self, file: PassFile, timeout: float, done: Callable[[], None], extra: dict[str, str] | None = None):
        super().__init__(media_type=file.media)
        self.file: PassFile | None = file
        self.timeout, self.done = timeout, done
        self.extra = [(k.lower().encode(), v.encode()) for k, v in (extra or {}).items()]

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        file = self.file
        assert file is not None
        self.file = None
        try:
            await send(
                {
                    "type": "http.response.start",
                    "status": 200,
                    "headers": [
                        (b"content-type", file.media.encode()),
                        (b"content-length", str(file.size).encode()),
                        (b"cache-control", b"no-cache"),
                        *self.extra,
                    ],
                }
            )
            for piece in file.chunks():
                with anyio.move_on_after(self.timeout) as waiting:
                    await send({"type": "http.response.body", "body": piece, "more_body": True})
                if waiting.cancelled_caught:
                    await _drop(scope)
                    return
                if await _left(receive):  # (a send to a closed connection returns at once: stop copying)
                    return
                await anyio.sleep(0)  # (a turn of the event loop between chunks, for the other requests)
            await send({"type": "http.response.body", "body": b"", "more_body": False})
        finally:
            del file
            self.done()


async def _left(receive: Any) -> bool:
    """Whether the client has gone, looked at without waiting (as :meth:`Request.is_disconnected` looks)."""
    with anyio.CancelScope() as look:
        look.cancel()
        message = await receive()
        return bool(message.get("type") == "http.disconnect")
    return False


async def _drop(scope: Any) -> None:
    """Close a connection whose client does not read, dropping what is queued for it (``phongray.abort``, set by
    :class:`service.http.server.Protocol`); where there is no such hook, by failing the answer."""
    abort = scope.get("phongray.abort")
    if abort is None:
        raise Gone("the client did not read the answer within send_timeout")
    abort()
    for _ in range(3):  # (the connection's loss is taken in first: the server then logs no unfinished answer)
        await anyio.sleep(0)
