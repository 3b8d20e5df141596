"""Running one sandboxed command to its end: the wall-time limit, the output kept, the time used.

The command starts in a process group of its own; at the wall-time limit (or when its standard output grows
past what is kept) the group is killed with ``SIGKILL``.  That kills bubblewrap, and with it, through
``--die-with-parent``, the sandbox's first process: when the first process of a PID namespace dies, the kernel
kills every other process in it, so no process of the run outlives it (a daemon started with ``setsid`` and a
double fork included).  Standard error is read as it comes and only its end kept; standard output, where a
command's is kept, up to a limit (the sandbox's own is the null device: :mod:`service.programs.runner`).  The
wall and CPU time are measured by the parent (``wait4``'s usage: the CPU time of the command and of the
processes reaped in it) and by the run's guard, which also says how long the run waited for a CPU.
"""

from __future__ import annotations

import array
import contextlib
import fcntl
import json
import os
import select
import signal
import subprocess
import termios
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
    stdout_bytes: int  # standard output kept (beyond it, the command is killed); 0: the null device
    stderr_bytes: int  # the end of standard error kept
    status: tuple[int, int] | None = None  # a pipe (read, write) bubblewrap writes its --json-status-fd to
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
    started: bool | None = None  # bubblewrap's word: it ran the command (None: no sandbox)
    waited_seconds: float = 0.0  # how long the run's threads waited, ready, for a CPU (its guard's measure)

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


#: the size asked for the parent's end of a pipe it drains (the most an unprivileged process may ask, 1 MiB)
PIPE_BYTES = 1 << 20
F_SETPIPE_SZ = 1031
#: bytes of a command's standard error drained as fast as they come; past them, a pipe's worth at most every
#: THROTTLE seconds (a program that floods it is slowed to 100 MiB/s, and costs the parent ~1% of a CPU)
FREE_BYTES, THROTTLE = 16 << 20, 0.01


class _Tail:
    """The last ``limit`` bytes of a pipe.  What is more than the limit behind what is waiting in the pipe is
    never read: it is moved to the null device by the kernel (``splice``, no copy), so a program that floods
    its standard error costs the parent a few calls per mebibyte, not a copy of every byte; and past
    :data:`FREE_BYTES`, the pipe is drained at most every :data:`THROTTLE` seconds."""

    def __init__(self, limit: int):
        self.limit, self.data, self.seen = limit, b"", 0

    def read(self, pipe: IO[bytes]) -> None:
        fd = pipe.fileno()
        with contextlib.suppress(OSError):
            fcntl.fcntl(fd, F_SETPIPE_SZ, PIPE_BYTES)
        null = os.open(os.devnull, os.O_WRONLY | os.O_CLOEXEC)
        waiting = array.array("i", [0])
        try:
            while True:
                if self.seen > FREE_BYTES:
                    time.sleep(THROTTLE)
                fcntl.ioctl(fd, termios.FIONREAD, waiting)
                if waiting[0] > self.limit:
                    self.seen += os.splice(fd, null, waiting[0] - self.limit)
                chunk = os.read(fd, max(CHUNK, self.limit))
                if not chunk:
                    break
                self.seen += len(chunk)
                self.data = (self.data + chunk)[-self.limit :]
        finally:
            os.close(null)
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
    fds = command.fds if command.status is None else (command.status[1], *command.fds)
    try:
        return subprocess.Popen(
            command.argv,
            cwd=command.cwd,
            env=command.env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE if command.stdout_bytes else subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            start_new_session=True,
            pass_fds=fds,
        )
    finally:
        for fd in fds:
            os.close(fd)


class _Status:
    """bubblewrap's ``--json-status-fd``: a line ``{"child-pid": N, ...}`` once it has started the sandbox's
    first process, and a line ``{"exit-code": N}`` when the command it ran has ended, written only when it did
    run it (its set-up done and the command executed: bubblewrap knows it by a pipe of its own that closes on
    ``exec``).  Only bubblewrap writes it: its sandbox's processes never hold it, so no program can forge it."""

    def __init__(self, fd: int | None):
        self.fd, self.text = fd, b""

    def child(self) -> int | None:
        """The sandbox's first process, once bubblewrap has started it; None when it failed before."""
        while self.fd is not None and b"\n" not in self.text:
            chunk = os.read(self.fd, 4096)
            if not chunk:
                break
            self.text += chunk
        try:
            return int(json.loads(self.text.split(b"\n")[0])["child-pid"])
        except (ValueError, KeyError, TypeError):
            return None

    def started(self) -> bool | None:
        """Whether bubblewrap ran the command (read to the end, once bubblewrap has ended); None: no sandbox."""
        if self.fd is None:
            return None
        poller = select.poll()
        poller.register(self.fd, select.POLLIN)
        while poller.poll(DRAIN_SECONDS * 1000) and (chunk := os.read(self.fd, 4096)):
            self.text += chunk
        return b'"exit-code"' in self.text

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def _pidfd(pid: int | None) -> int | None:
    """A pidfd of the sandbox's first process (read from bubblewrap's status as soon as it is started, while
    bubblewrap is its parent and it cannot have been reaped); None when there is none."""
    try:
        return None if pid is None else os.pidfd_open(pid)
    except OSError:
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


def _watch(group: _Group, head: _Head, stop: threading.Event, command: Command) -> threading.Event:
    """Kill the group at the wall-time limit (the event returned is then set; its guard looks a last time
    first) or once ``head`` overflows."""
    timed_out = threading.Event()

    def watch() -> None:
        if not stop.wait(command.wall_seconds):
            timed_out.set()
            if command.guard is not None:
                command.guard.last_look()
            group.kill()
        elif head.overflowed:
            group.kill()

    threading.Thread(target=watch, daemon=True).start()
    return timed_out


def _read(proc: subprocess.Popen[bytes], head: _Head, tail: _Tail) -> list[threading.Thread]:
    assert proc.stderr is not None
    readers = [threading.Thread(target=tail.read, args=(proc.stderr,), daemon=True)]
    if proc.stdout is not None:  # (standard output kept)
        readers.append(threading.Thread(target=head.read, args=(proc.stdout,), daemon=True))
    for reader in readers:
        reader.start()
    return readers


def run_command(command: Command) -> Finished:
    """Run ``command`` to its end (or the parent's kill), and say how it ended; when it is a sandbox, wait
    until every process in it has ended too.  Its process group is killed once it has ended, before it is
    reaped, so that the group's id cannot have been reused."""
    start = time.monotonic()
    status = _Status(None if command.status is None else command.status[0])
    try:
        proc = _start(command)
    except BaseException:
        status.close()
        raise
    stop = threading.Event()
    head, tail, group = _Head(command.stdout_bytes, stop), _Tail(command.stderr_bytes), _Group(proc.pid)
    readers = _read(proc, head, tail)
    timed_out = _watch(group, head, stop, command)
    pidfd, started = None, None
    try:
        inside = status.child()
        pidfd = _pidfd(inside)
        if command.guard is not None:
            command.guard.start(proc.pid, group.kill, inside)
    except BaseException:
        group.kill()
        raise
    finally:
        status_code, cpu = group.reap()
        proc.returncode = os.waitstatus_to_exitcode(status_code)
        stop.set()
        _await_teardown(pidfd)
        exceeded = None if command.guard is None else command.guard.stop()
        started = status.started()
        status.close()
    wall = time.monotonic() - start
    for reader in readers:
        reader.join(DRAIN_SECONDS)
    timed = timed_out.is_set() and exceeded is None
    guard = command.guard
    held_by, waited = ("", 0.0) if guard is None else (guard.name, guard.waited_seconds)
    cpu = cpu if guard is None else max(cpu, guard.cpu_seconds)
    out = b"".join(head.parts)
    return Finished(status_code, timed, head.overflowed, out, tail.data, wall, cpu, exceeded, held_by, started, waited)
