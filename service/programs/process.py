"""Running one sandboxed command to its end: the wall-time limit, the output kept, the time used.

The command starts in a process group of its own; at the wall-time limit (or when its standard output grows
past what is kept) the group is killed with ``SIGKILL``.  That kills bubblewrap, and with it, through
``--die-with-parent``, the sandbox's first process: when the first process of a PID namespace dies, the kernel
kills every other process in it, so no process of the run outlives it (a daemon started with ``setsid`` and a
double fork included).  Standard error is read as it comes and only its end kept; standard output (a build's
tar stream) is kept up to a limit.  The wall and CPU time are measured by the parent (``wait4``'s usage: the
CPU time of the command and of the processes reaped in it).
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import threading
import time
from dataclasses import dataclass
from typing import IO, TYPE_CHECKING

if TYPE_CHECKING:
    from .guard import Guard

#: bytes read from a pipe at a time
CHUNK = 65536


@dataclass(frozen=True)
class Command:
    """What to run, where, and how much of its output to keep."""

    argv: list[str]
    cwd: str
    env: dict[str, str]
    wall_seconds: float
    stdout_bytes: int  # standard output kept (beyond it, the command is killed)
    stderr_bytes: int  # the end of standard error kept
    info: tuple[int, int] | None = None  # a pipe (read, write) bubblewrap writes its --info-fd to
    fds: tuple[int, ...] = ()  # more descriptors the command is given (and the parent closes once it has)
    guard: Guard | None = None  # what holds the run's memory and processes (started with the command)


@dataclass(frozen=True)
class Finished:
    """How a command ended: its wait status, whether the parent killed it and why, and what it printed."""

    status: int  # the raw wait status
    timed_out: bool
    stdout_overflow: bool
    stdout: bytes
    stderr_tail: bytes
    wall_seconds: float
    cpu_seconds: float
    exceeded: str | None = None  # the limit the run's guard ended it for (``memory``, ``processes``)
    held_by: str = ""  # the guard's name (``the watchdog``, ``its cgroup``)

    @property
    def exit_code(self) -> int | None:
        return os.waitstatus_to_exitcode(self.status) if os.WIFEXITED(self.status) else None


class _Head:
    """The first ``limit`` bytes of a pipe; past them, ``overflowed`` and ``stop`` set (the command is killed)."""

    def __init__(self, limit: int, stop: threading.Event):
        self.limit, self.stop, self.size, self.overflowed = limit, stop, 0, False
        self.parts: list[bytes] = []

    def read(self, pipe: IO[bytes]) -> None:
        while chunk := pipe.read1(CHUNK):  # type: ignore[attr-defined]
            if self.size + len(chunk) > self.limit:
                self.overflowed = True
                self.stop.set()
                break
            self.parts.append(chunk)
            self.size += len(chunk)
        pipe.close()


class _Tail:
    """The last ``limit`` bytes of a pipe."""

    def __init__(self, limit: int):
        self.limit, self.data = limit, b""

    def read(self, pipe: IO[bytes]) -> None:
        while chunk := pipe.read1(CHUNK):  # type: ignore[attr-defined]
            self.data = (self.data + chunk)[-self.limit :]
        pipe.close()


#: how long the parent waits, once the command has ended, for the rest of its output: only a process that
#: escaped the group (possible without the sandbox) still holds the pipes then, and is not waited for
DRAIN_SECONDS = 2.0


def _kill(pid: int) -> None:
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


#: seconds the parent waits for the sandbox's first process to end once bubblewrap has (it kills the
#: sandbox's other processes first): far more than killing a few dozen processes takes
TEARDOWN_SECONDS = 30.0


def _start(command: Command) -> subprocess.Popen[bytes]:
    fds = command.fds if command.info is None else (command.info[1], *command.fds)
    try:
        return subprocess.Popen(
            command.argv,
            cwd=command.cwd,
            env=command.env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,
            pass_fds=fds,
        )
    finally:
        for fd in fds:
            os.close(fd)


def _sandbox_pidfd(info: tuple[int, int] | None) -> int | None:
    """A pidfd of the sandbox's first process, from bubblewrap's ``--info-fd`` (``{"child-pid": N}``, written
    as soon as it is started, while bubblewrap is its parent and it cannot have been reaped); None when
    there is none (bubblewrap failed, or the process is gone already)."""
    if info is None:
        return None
    with os.fdopen(info[0], "rb") as pipe:
        text = pipe.read(4096)  # (to its end: bubblewrap closes it once it has written, at its start)
    try:
        return os.pidfd_open(int(json.loads(text)["child-pid"]))
    except (ValueError, KeyError, TypeError, OSError):
        return None


def _await_teardown(pidfd: int | None) -> None:
    """Wait until the sandbox's first process has ended: the kernel has then killed every other process of
    its PID namespace (it ends only once they are gone), so none outlives the run."""
    if pidfd is None:
        return
    try:
        poller = select.poll()
        poller.register(pidfd, select.POLLIN)
        poller.poll(TEARDOWN_SECONDS * 1000)
    finally:
        os.close(pidfd)


class _Group:
    """The command's process group, killed at most until it is reaped (so never a group that reused its id)."""

    def __init__(self, pid: int):
        self.pid, self.lock, self.reaped = pid, threading.Lock(), False

    def kill(self) -> None:
        with self.lock:
            if not self.reaped:
                _kill(self.pid)

    def reap(self) -> tuple[int, float]:
        """Kill what is left of the group and reap the command, once it has ended: its wait status and the
        CPU time it and the processes it reaped used."""
        os.waitid(os.P_PID, self.pid, os.WEXITED | os.WNOWAIT)
        with self.lock:
            _kill(self.pid)
            _, status, usage = os.wait4(self.pid, 0)
            self.reaped = True
        return status, usage.ru_utime + usage.ru_stime


def _watch(group: _Group, head: _Head, stop: threading.Event, wall: float) -> threading.Event:
    """Kill the group at the wall-time limit (the event returned is then set) or once ``head`` overflows."""
    timed_out = threading.Event()

    def watch() -> None:
        if not stop.wait(wall):
            timed_out.set()
            group.kill()
        elif head.overflowed:
            group.kill()

    threading.Thread(target=watch, daemon=True).start()
    return timed_out


def _read(proc: subprocess.Popen[bytes], head: _Head, tail: _Tail) -> list[threading.Thread]:
    assert proc.stdout is not None and proc.stderr is not None
    readers = [
        threading.Thread(target=head.read, args=(proc.stdout,), daemon=True),
        threading.Thread(target=tail.read, args=(proc.stderr,), daemon=True),
    ]
    for reader in readers:
        reader.start()
    return readers


def run_command(command: Command) -> Finished:
    """Run ``command`` to its end (or the parent's kill), and say how it ended; when it is a sandbox, wait
    until every process in it has ended too.  Its process group is killed once it has ended, before it is
    reaped, so that the group's id cannot have been reused."""
    start = time.monotonic()
    try:
        proc = _start(command)
    except BaseException:
        if command.info is not None:
            os.close(command.info[0])
        raise
    stop = threading.Event()
    head, tail, group = _Head(command.stdout_bytes, stop), _Tail(command.stderr_bytes), _Group(proc.pid)
    readers = _read(proc, head, tail)
    timed_out = _watch(group, head, stop, command.wall_seconds)
    if command.guard is not None:
        command.guard.start(proc.pid, group.kill)
    pidfd = None
    try:
        pidfd = _sandbox_pidfd(command.info)
    except BaseException:
        group.kill()
        raise
    finally:
        status, cpu = group.reap()
        proc.returncode = os.waitstatus_to_exitcode(status)
        stop.set()
        _await_teardown(pidfd)
        exceeded = None if command.guard is None else command.guard.stop()
    wall = time.monotonic() - start
    for reader in readers:
        reader.join(DRAIN_SECONDS)
    timed = timed_out.is_set() and exceeded is None
    held_by = "" if command.guard is None else command.guard.name
    return Finished(status, timed, head.overflowed, b"".join(head.parts), tail.data, wall, cpu, exceeded, held_by)
