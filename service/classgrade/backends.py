"""Where the tasks of class grading run: a pool of processes, a Dask cluster, or a running service."""

from __future__ import annotations

import concurrent.futures as futures
import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from functools import partial
from typing import Any

from ..settings import Settings
from . import faults, tasks
from .errors import ClassError
from .remote import server_grade, server_render


def die_with_parent(parent: int, prctl: bool) -> None:
    """Initializer of a pool process: it ends when grade-class does, however grade-class ends (SIGKILL, the
    OOM killer), never left running.  On Linux the kernel kills it (PR_SET_PDEATHSIG; only when the pool was
    made by the main thread, as the signal comes when the creating thread ends); everywhere, a watchdog thread
    sees the parent gone."""
    if prctl and sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)  # 1: PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the signal was asked for
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.25)
        os._exit(1)

    threading.Thread(target=watch, name="phongray-parent-watch", daemon=True).start()


class Backend:
    """Where the tasks run, checked before any is sent: an executor, the render task and the grade task.  After
    a fault of the executor itself (a pool process killed, the Dask scheduler lost) :meth:`reset` makes a new
    one; a server's faults are retried per request (:func:`~service.classgrade.remote.patient`)."""

    def __init__(self, server: str | None, cluster: str | None, jobs: int | None, work: int, api_key: str | None,
                 cluster_wait: float, limits: Settings | None):
        self.cluster, self.cluster_wait = cluster, cluster_wait
        self.client: Any = None
        self.workers = max(1, min(jobs or os.cpu_count() or 1, work))
        self.executor: futures.Executor | None = None
        #: what a fault of the executor raises (for a result, or for a submission)
        self.faults: tuple[type[BaseException], ...] = ()
        self.render: Callable[..., Any] = partial(tasks.render_task, limits=limits)
        self.grade: Callable[..., Any] = tasks.local_grade
        if server:
            from ..client import ServerError, check

            try:
                check(server, api_key)
            except ServerError as exc:
                raise ClassError(f"--server {server}: {exc}") from None
            self.name = f"--server {server}"
            self.executor = futures.ThreadPoolExecutor(max_workers=jobs or 4)
            self.render = partial(server_render, server, api_key)
            self.grade = partial(server_grade, server, api_key)
        elif cluster:
            self.name = f"--cluster {cluster}"
            self.faults = (futures.CancelledError, OSError, TimeoutError)
            self._connect()
        elif work:
            self.name = "the pool of processes"
            self.faults = (BrokenProcessPool,)
            self._pool()

    def _pool(self) -> None:
        context = multiprocessing.get_context("spawn")  # no fork of a process that may hold threads
        self.executor = futures.ProcessPoolExecutor(
            max_workers=self.workers, mp_context=context, initializer=die_with_parent,
            initargs=(os.getpid(), threading.current_thread() is threading.main_thread()))

    def _connect(self, timeout: float = 10.0) -> None:
        """A client of the scheduler (a new one when the old has lost it) with a worker, and its executor."""
        from ..cluster import client, connect_timeout, wait_for_workers

        assert self.cluster is not None
        started = time.monotonic()
        if self.client is None or getattr(self.client, "status", "running") != "running":
            self._close_client()
            self.client = client(self.cluster, connect_timeout(timeout, self.cluster_wait))
        wait_for_workers(self.client, self.cluster, self.cluster_wait, time.monotonic() - started)
        self.executor = self.client.get_executor(retries=2)

    def _close_client(self) -> None:
        old, self.client = self.client, None
        if old is not None:
            with contextlib.suppress(Exception):
                old.close(timeout=5)

    def reset(self) -> None:
        """A new executor after a fault of the old one (:class:`ClusterError` if the cluster cannot be had)."""
        if self.executor is not None:
            with contextlib.suppress(Exception):
                self.executor.shutdown(wait=False, cancel_futures=True)
        if self.cluster:
            self._connect(faults.RECONNECT_TIMEOUT)
        else:
            self._pool()

    def close(self, wait: bool = True) -> None:
        """Done with: ``wait`` for what still runs (not after an error or an interruption: a pool process then
        ends with its task, or with grade-class)."""
        if self.executor is not None:
            with contextlib.suppress(Exception):
                self.executor.shutdown(wait=wait, cancel_futures=True)
        self._close_client()


