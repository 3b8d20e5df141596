"""The processes of the local pool: how they start, cheaply, and how they end with the grading process.

A pool process is forked from a forkserver (:func:`context`): one process, started once per grading process,
that has imported phongray (NumPy, Embree, the tracer, the grading) and forks each pool process from that
state, so that a pool process starts in milliseconds instead of the second a fresh interpreter takes to import
them again (each run of grade-class pays it once, not once per process; a process that grades class after class,
the service or a test session, once in all).  Where there is no forkserver, the processes are spawned.

A forked process starts from the forkserver's state, not the grading process's: what a spawned process would
take from the grading process when it starts, it is given by :func:`join` instead.  multiprocessing gives it the
working folder, ``sys.path`` and the main module; :func:`join` gives it the environment (a TA's
``PHONGRAY_*`` settings, ``TMPDIR``) as the grading process holds it when the pool is made.

A pool process ends with the grading process, however that ends (SIGKILL, the OOM killer): it watches a pipe
whose only writing end the grading process holds (:func:`lifeline`), and the kernel closes that end when the
grading process dies, whoever the pool process's parent is (a forkserver's process is not the grading
process's child).  On Linux the kernel also kills it when its parent ends (PR_SET_PDEATHSIG)."""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import tempfile
import threading
from multiprocessing.connection import Connection
from multiprocessing.context import BaseContext
from typing import Any

#: what a pool process imports before it is forked: the tasks and what they import (tracer, NumPy, Embree,
#: Pillow, the grading and the diagnosis), and the running of students' programs
PRELOAD = ["service.classgrade.tasks", "service.classgrade.programs", "PIL.Image", "PIL.PngImagePlugin"]

#: the pipe of :func:`lifeline`, by the process that made it: (pid, reading end, writing end)
_LIFELINE: list[tuple[int, Connection, Connection]] = []


def context() -> BaseContext:
    """Where the pool's processes come from: a forkserver that has imported :data:`PRELOAD`, or, where there
    is none, spawned interpreters.  Never forked from the grading process itself, which may hold threads."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    forkserver = multiprocessing.get_context("forkserver")
    forkserver.set_forkserver_preload(PRELOAD)  # (read when the forkserver starts, at the first pool process)
    return forkserver


def lifeline() -> Connection:
    """The reading end of a pipe whose writing end only this process holds, for its pool processes to watch:
    it reads end of file when this process is gone.  One a process, kept while it lives (a pool made after
    another is given the same); a process forked from this one makes its own."""
    if not _LIFELINE or _LIFELINE[0][0] != os.getpid():
        reading, writing = multiprocessing.Pipe(duplex=False)
        _LIFELINE[:] = [(os.getpid(), reading, writing)]
    return _LIFELINE[0][1]


def initargs(context: BaseContext) -> tuple[Any, ...]:
    """The arguments of :func:`join` for a pool of ``context``'s processes made now by this process: the kernel's
    signal at a parent's end is to be trusted where the parent is the forkserver, or this process if the pool is
    made by its main thread (the signal comes when the creating thread ends)."""
    prctl = context.get_start_method() == "forkserver" or threading.current_thread() is threading.main_thread()
    return lifeline(), dict(os.environ), prctl


def join(line: Connection, environ: dict[str, str], prctl: bool) -> None:
    """Initializer of a pool process: it takes the grading process's ``environ``, and ends when the grading
    process does: when ``line``, :func:`lifeline`'s reading end, reads end of file; on Linux with ``prctl``,
    also killed by the kernel when its parent ends (the forkserver, which ends with the grading process; or a
    spawning grading process, if the pool was made by its main thread: the signal comes when the creating
    thread ends)."""
    if prctl and sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)  # 1: PR_SET_PDEATHSIG
    os.environ.clear()
    os.environ.update(environ)
    tempfile.tempdir = None  # (read TMPDIR again, as a new interpreter would)

    def watch() -> None:
        with contextlib.suppress(EOFError, OSError):
            while True:
                line.recv_bytes()  # (nothing is sent: this returns at the end of file, the grading process gone)
        os._exit(1)

    threading.Thread(target=watch, name="phongray-grading-watch", daemon=True).start()
