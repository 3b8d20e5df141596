"""Spreading connections over a server's worker processes: the worker holding the fewest takes the next.

uvicorn's workers share one listening socket, and whichever worker's event
loop is first to wake takes a connection; two kept-alive clients can both land
on one worker, whose two renders then share one interpreter lock while the
other worker idles.  Here every worker keeps its count of open connections on
a shared :class:`Board` (one slot per worker: its pid and its count, written
by that worker alone), and a worker's event loop (:class:`BalancedLoop`)
accepts a waiting connection only when no other live worker holds fewer
(give or take a quarter of theirs, so that a flood is still taken at full
speed), and, while workers hold few, when none that holds as many accepted
less recently.  Otherwise it stands aside, and the least-loaded worker takes it.

The last rule is for counts that lag: a worker counts a closed connection
only when its event loop comes round to it, so for a moment after a client
leaves, its worker still counts it.  If two clients then connect at once to a
server whose workers count (1 stale, 0), the idle worker takes the first and
the counts tie at (1, 1); on counts alone it would take the second too, but
it has just accepted, so it stands aside for the other.

A worker never waits on another for long: once it has stood aside for
:data:`PATIENCE` seconds with a connection still waiting (the other worker
busy starting, or gone), it takes the connection itself.  Each accepted
connection is counted at once, and a worker asks again whether it is its turn
before it takes the next, so that two clients connecting at once are counted
between their accepts.

``phongray serve --workers N`` (N > 1) makes the board before uvicorn starts
its workers and removes it when the server stops; with one worker there is
nothing to spread, and no board.
"""

from __future__ import annotations

import asyncio
import fcntl
import mmap
import os
import select
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from ..settings import Settings

#: the environment variable that names the board's file, for the workers uvicorn spawns
BOARD_ENV = "PHONGRAY_BALANCE_BOARD"
#: slots on a board: more than any worker count a 2-core machine (or most others) runs
SLOTS = 64
#: the longest a worker stands aside for a connection that no other worker takes, in seconds (the default of
#: the ``balance_patience`` setting)
PATIENCE = 0.02
#: how often a worker standing aside looks again whether the connection is still waiting, in seconds
LOOK_AGAIN = 0.005


class Board:
    """A file mapped into every worker: per slot, a worker's pid and how many connections it holds open."""

    def __init__(self, path: str):
        self.path = path
        self._file = open(path, "r+b")  # noqa: SIM115 (held open for the life of the process)
        self._map = mmap.mmap(self._file.fileno(), SLOTS * 24)
        #: per slot: pid, open connections, and the monotonic clock (ns, the same in every process) at its last
        #: accept
        self._slots = np.frombuffer(self._map, dtype=np.int64).reshape(SLOTS, 3)
        self.slot: int | None = None

    @staticmethod
    def create() -> Board:
        folder = "/dev/shm" if os.path.isdir("/dev/shm") else None
        fd, path = tempfile.mkstemp(prefix="phongray-balance-", dir=folder)
        os.write(fd, bytes(SLOTS * 24))
        os.close(fd)
        return Board(path)

    def claim(self) -> None:
        """Take a free slot (or a dead worker's) for this process."""
        fcntl.flock(self._file.fileno(), fcntl.LOCK_EX)
        try:
            for k in range(SLOTS):
                pid = int(self._slots[k, 0])
                if pid == 0 or not _alive(pid):
                    self._slots[k] = (os.getpid(), 0, 0)
                    self.slot = k
                    return
        finally:
            fcntl.flock(self._file.fileno(), fcntl.LOCK_UN)

    def opened(self) -> None:
        if self.slot is not None:
            self._slots[self.slot, 1] += 1
            self._slots[self.slot, 2] = time.monotonic_ns()

    def closed(self) -> None:
        if self.slot is not None and self._slots[self.slot, 1] > 0:
            self._slots[self.slot, 1] -= 1

    def my_turn(self) -> bool:
        """Whether this worker holds no more connections than every other live worker, give or take a quarter
        of theirs: exactly even while workers hold few (two clients on two workers), and free to accept at full
        speed in a flood (hundreds of connections at once, which strict turns would take one by one).  While
        they hold few, a tie goes to the worker that accepted least recently (a count that lags behind a
        closed connection then costs no client its own worker: see the module)."""
        if self.slot is None:
            return True
        mine, my_last = int(self._slots[self.slot, 1]), int(self._slots[self.slot, 2])
        for k in np.flatnonzero(self._slots[:, 0] > 0).tolist():
            theirs, slack = int(self._slots[k, 1]), int(self._slots[k, 1]) // 4
            if k == self.slot or mine < theirs or (0 < slack and mine <= theirs + slack):
                continue
            if (mine > theirs + slack or my_last > int(self._slots[k, 2])) and _alive(int(self._slots[k, 0])):
                return False
        return True

    def counts(self) -> dict[int, int]:
        """Every claimed slot's pid and open connections (for tests)."""
        return {int(pid): int(n) for pid, n, _ in self._slots if pid > 0}

    def close(self) -> None:
        self._slots = np.zeros((0, 3), dtype=np.int64)  # (drop the view before the map it points into)
        self._map.close()
        self._file.close()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


#: this worker's board, when its server spreads connections (set by :func:`join`)
BOARD: Board | None = None


def join() -> Board | None:
    """This worker's place on the board its server made (None when there is none)."""
    global BOARD
    path = os.environ.get(BOARD_ENV)
    if BOARD is None and path:
        BOARD = Board(path)
        BOARD.claim()
    return BOARD


@contextmanager
def board_for(workers: int) -> Iterator[Board | None]:
    """A board for a server of ``workers`` processes, named to them by :data:`BOARD_ENV`, removed afterwards."""
    if workers <= 1:
        yield None
        return
    board = Board.create()
    os.environ[BOARD_ENV] = board.path
    try:
        yield board
    finally:
        os.environ.pop(BOARD_ENV, None)
        board.close()
        os.unlink(board.path)


class BalancedLoop(asyncio.SelectorEventLoop):
    """An event loop whose listening sockets accept a connection only on this worker's turn (see the module).

    A connection is counted the moment it is accepted (before its protocol exists, a turn of the loop later),
    and uncounted by :class:`service.http.server.Protocol` when it is lost."""

    _aside_since: float | None = None
    #: how long this worker stands aside (the ``balance_patience`` setting; set by :func:`balanced_loop`)
    patience: float = PATIENCE

    def _accept_connection(
        self,
        protocol_factory: Any,
        sock: Any,
        sslcontext: Any = None,
        server: Any = None,
        backlog: int = 100,
        *args: Any,
    ) -> None:
        board = BOARD
        if board is None:
            super()._accept_connection(protocol_factory, sock, sslcontext, server, backlog, *args)  # type: ignore[misc]
            return
        if not board.my_turn():
            now = time.monotonic()
            if self._aside_since is None:
                self._aside_since = now
            if now - self._aside_since < self.patience:  # stand aside: stop watching the socket for a moment
                fd = sock.fileno()
                self._remove_reader(fd)  # type: ignore[attr-defined]
                self.call_later(
                    LOOK_AGAIN, self._watch_again, fd, protocol_factory, sock, sslcontext, server, backlog, *args
                )
                return
        self._aside_since = None
        for _ in range(backlog):  # while it is this worker's turn (each accept counts at once)
            try:
                conn, addr = sock.accept()
            except (BlockingIOError, InterruptedError, ConnectionAbortedError):
                return  # (none left, or another worker took it)
            except OSError:  # as asyncio handles it (out of file descriptors: it pauses, and tries again)
                super()._accept_connection(protocol_factory, sock, sslcontext, server, 1, *args)  # type: ignore[misc]
                return
            conn.setblocking(False)
            board.opened()
            self.create_task(
                self._accept_connection2(  # type: ignore[attr-defined]
                    protocol_factory, conn, {"peername": addr}, sslcontext, server, *args
                )
            )
            if not board.my_turn():
                return

    def _watch_again(
        self, fd: int, protocol_factory: Any, sock: Any, sslcontext: Any, server: Any, backlog: int, *args: Any
    ) -> None:
        if sock.fileno() == -1 or (server is not None and not server.is_serving()):
            return  # (the server closed meanwhile)
        if not select.select([fd], [], [], 0)[0]:
            self._aside_since = None  # another worker took what was waiting
        self._add_reader(  # type: ignore[attr-defined]
            fd, self._accept_connection, protocol_factory, sock, sslcontext, server, backlog, *args
        )


def balanced_loop() -> asyncio.AbstractEventLoop:
    """The loop factory of a worker that spreads connections (uvicorn's ``loop``)."""
    join()
    loop = BalancedLoop()
    loop.patience = Settings.from_env().balance_patience
    return loop
