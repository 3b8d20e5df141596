"""Faults of where the work runs (a pool process killed, the Dask scheduler lost, a server connection reset):
every task run on an executor, retried with backoff on a new one."""

from __future__ import annotations

import concurrent.futures as futures
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Protocol

from ..course.errors import ClassError
from ..render.cluster import ClusterError

#: a fault of the pool, the cluster or the server (a lost connection) is retried this many times ...
RETRIES = 4
#: ... after this many seconds, doubled at each retry (0.5 + 1 + 2 + 4 s: a restarting server worker is back)
BACKOFF = 0.5
#: seconds to reach a lost Dask scheduler again, at each retry
RECONNECT_TIMEOUT = 10.0


def one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    if isinstance(exc, BrokenProcessPool):
        return "a pool process died (killed, or out of memory)"
    if isinstance(exc, futures.CancelledError):
        return f"the work was cancelled ({text or 'the scheduler was lost'})"

    if isinstance(exc, ClusterError) and text:
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class Executing(Protocol):
    """What :func:`run_tasks` needs of where the work runs (a :class:`service.classgrade.backends.Backend`):
    its name in a message, its executor, what a fault of the executor raises, and a new executor after one."""

    name: str
    faults: tuple[type[BaseException], ...]
    executor: futures.Executor | None

    def reset(self) -> None: ...


def run_tasks(  # noqa: C901 (every fault of a task, retried in one loop)
    backend: Executing,
    tasks: dict[Any, tuple[Callable[..., Any], tuple[Any, ...]]],
    done: Callable[[Any, Any], None],
    kept: Callable[[], str],
) -> None:
    """Run every task on the backend; ``done(key, result)`` keeps each result as it comes (so that no finished
    work is lost, whatever happens next).  A fault of the executor (``backend.faults``) is retried
    :data:`RETRIES` times with backoff on a new one, with only the unfinished tasks; then the run stops with
    :class:`ClassError` (one line, saying what ``kept()`` kept).  Any other error stops it once every task
    already running has finished and been kept."""
    pending = dict(tasks)
    attempt = 0
    while pending:
        fault: BaseException | None = None
        fatal: BaseException | None = None
        submitted: dict[Any, Any] = {}
        assert backend.executor is not None
        try:
            for key, (func, args) in pending.items():
                submitted[backend.executor.submit(func, *args)] = key
        except backend.faults as exc:
            fault = exc
        for fut in futures.as_completed(submitted):
            key = submitted[fut]
            try:
                result = fut.result()
            except backend.faults as exc:
                fault = fault or exc
                continue
            except futures.CancelledError:  # cancelled below, after an error
                continue
            except Exception as exc:
                if fatal is None:
                    fatal = exc
                    for other in submitted:
                        other.cancel()
                continue
            done(key, result)
            del pending[key]
        if fatal is not None:
            raise fatal
        while pending and fault is not None:
            if attempt >= RETRIES:
                raise ClassError(
                    f"{backend.name}: {one_line(fault)} (tried {RETRIES + 1} times); stopped with "
                    f"{len(pending)} tasks unfinished; {kept()}: run again to resume"
                )
            time.sleep(BACKOFF * 2**attempt)
            attempt += 1
            try:
                backend.reset()
                fault = None
            except Exception as exc:
                if not isinstance(exc, (ClusterError, *backend.faults)):
                    raise
                fault = exc
