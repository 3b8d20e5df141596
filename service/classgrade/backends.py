"""Where the tasks of class grading run: a pool of processes here, a Dask cluster, or a running service, each a
:class:`Backend`: an executor the tasks are submitted to, the render task and the grade task (picklable, taking
bytes and a :class:`~service.classgrade.records.GradeJob`), what a fault of the executor raises, and how a new
executor is had after one."""

from __future__ import annotations

import concurrent.futures as futures
import contextlib
import os
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from functools import partial
from typing import Any

from ..client import ServerError, check
from ..course.errors import ClassError
from ..render.cluster import client, connect_timeout, wait_for_workers
from ..settings import Settings
from . import faults, processes, tasks
from .records import ClassRun, GradeJob, Marked
from .remote import server_grade, server_render


class Backend:
    """Where the tasks run, checked before any is sent.  After a fault of the executor itself (one of
    :attr:`faults`: a pool process killed, the Dask scheduler lost) :meth:`reset` makes a new one; a server's
    faults are retried per request (:func:`~service.classgrade.remote.patient`)."""

    #: how the run names where its work goes, in a message
    name = ""
    #: what a fault of the executor raises (for a result, or for a submission)
    faults: tuple[type[BaseException], ...] = ()

    def __init__(self) -> None:
        self.executor: futures.Executor | None = None

    def render(self) -> Callable[[bytes], tuple[bytes | None, str]]:
        """The render task: a scene's text → its reference PNG, or None and why not."""
        raise NotImplementedError

    def grade(self) -> Callable[[GradeJob], Marked]:
        """The grade task: a pair's job → its grade (:class:`~.records.Marked`)."""
        return tasks.local_grade

    def reset(self) -> None:
        """A new executor after a fault of the old one."""

    def close(self, wait: bool = True) -> None:
        """Done with: ``wait`` for what still runs (not after an error or an interruption: a pool process then
        ends with its task, or with grade-class)."""
        if self.executor is not None:
            with contextlib.suppress(Exception):
                self.executor.shutdown(wait=wait, cancel_futures=True)


class LocalBackend(Backend):
    """A pool of processes here (forked from a forkserver, each ending with grade-class:
    :mod:`~service.classgrade.processes`), one per core or ``jobs``, at most one
    per task; none for a run with nothing to do."""

    name = "the pool of processes"
    faults = (BrokenProcessPool,)

    def __init__(self, jobs: int | None, work: int, limits: Settings | None) -> None:
        super().__init__()
        self.workers = max(1, min(jobs or os.cpu_count() or 1, work))
        self.limits = limits
        if work:
            self._pool()

    def render(self) -> Callable[[bytes], tuple[bytes | None, str]]:
        return partial(tasks.render_task, limits=self.limits)

    def grade(self) -> Callable[[GradeJob], Marked]:
        return tasks.local_grade  # (looked up now: a test may put another in its place)

    def _pool(self) -> None:
        context = processes.context()
        self.executor = futures.ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=context,
            initializer=processes.join,
            initargs=processes.initargs(context),
        )

    def reset(self) -> None:
        super().close(wait=False)
        self._pool()


class DaskBackend(Backend):
    """A Dask cluster, its scheduler at ``address``: a client with a worker (waited for ``wait`` seconds), and
    its executor; the same tasks as a local pool's."""

    faults = (futures.CancelledError, OSError, TimeoutError)

    def __init__(self, address: str, wait: float, limits: Settings | None) -> None:
        super().__init__()
        self.name = f"--cluster {address}"
        self.address, self.wait, self.limits = address, wait, limits
        self.client: Any = None
        self._connect()

    def render(self) -> Callable[[bytes], tuple[bytes | None, str]]:
        return partial(tasks.render_task, limits=self.limits)

    def _connect(self, timeout: float = 10.0) -> None:
        """A client of the scheduler (a new one when the old has lost it) with a worker, and its executor."""
        started = time.monotonic()
        if self.client is None or getattr(self.client, "status", "running") != "running":
            self._close_client()
            self.client = client(self.address, connect_timeout(timeout, self.wait))
        wait_for_workers(self.client, self.address, self.wait, time.monotonic() - started)
        self.executor = self.client.get_executor(retries=2)

    def _close_client(self) -> None:
        old, self.client = self.client, None
        if old is not None:
            with contextlib.suppress(Exception):
                old.close(timeout=5)

    def reset(self) -> None:
        """A new executor, of a new client if the old lost the scheduler (:class:`ClusterError` if the cluster
        cannot be had)."""
        super().close(wait=False)
        self._connect(faults.RECONNECT_TIMEOUT)

    def close(self, wait: bool = True) -> None:
        super().close(wait)
        self._close_client()


class ServerBackend(Backend):
    """A running service at ``url``, checked (and the key ``api_key`` with it) before any task is sent; the
    requests are sent by ``jobs`` threads (4 by default)."""

    def __init__(self, url: str, api_key: str | None, jobs: int | None) -> None:
        super().__init__()
        try:
            check(url, api_key)
        except ServerError as exc:
            said = str(exc)
            raise ClassError(said if said.startswith("--server") else f"--server {url}: {said}") from None
        self.name = f"--server {url}"
        self.url, self.api_key = url, api_key
        self.executor = futures.ThreadPoolExecutor(max_workers=jobs or 4)

    def render(self) -> Callable[[bytes], tuple[bytes | None, str]]:
        return partial(server_render, self.url, self.api_key)

    def grade(self) -> Callable[[GradeJob], Marked]:
        return partial(server_grade, self.url, self.api_key)


def open_backend(run: ClassRun, work: int, limits: Settings | None) -> Backend:
    """The backend of the run, for ``work`` tasks: its server, its cluster, or a pool here (none made for no
    work); the renders held to ``limits`` where they run here or on the cluster."""
    if run.server:
        return ServerBackend(run.server, run.api_key, run.jobs)
    if run.cluster:
        return DaskBackend(run.cluster, run.cluster_wait, limits)
    return LocalBackend(run.jobs, work, limits)
