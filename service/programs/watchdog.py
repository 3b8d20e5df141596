"""The watchdog: a run's memory (and, where nothing else counts them, its processes) held to its limits by
looking, where no cgroup of its own can be made for it (:mod:`service.programs.cgroup`).

Ten times a second it finds the run's processes (every descendant of the command phongray started: in the
sandbox, its PID namespace, whose orphans are adopted by its first process, so a daemon stays among them),
and adds up what they hold (:mod:`service.programs.usage`): their pages (private, and their share of those
they share: a child forked from a large process, which shares its pages until it writes them, counts its
share only), page tables and mappings (what each mapping costs the kernel), what their open files can hold
in the kernel (a socket's or a pipe's buffers, :data:`~service.programs.usage.FILE_BYTES` each), and what
the sandbox's tmpfs folders hold (their bytes and files).  Past the limit it kills the run, which then ends
as ``memory``.  Between two looks a run can go over the limit for a tenth of a second (where its processes
share pages or make many mappings, until the next walk of their page tables and mappings:
:class:`~service.programs.usage.Shares`); each process is also held to its address space (``RLIMIT_AS``), so
no one process goes past it.  However many processes and mappings a run makes, the watchdog spends at most
:data:`~service.programs.usage.FRACTION` of one CPU walking their page tables and mappings (its own CPU time, not
the wall time a busy machine stretches a walk to); every other look costs the grader a read of a few small files
per process and thread.  When the run's wall time is up, one last look (a walk, whatever the budget) comes before
the kill, so that a run then over its memory ends as ``memory`` however late a busy machine let the looks come.

Where it counts processes too (a run without the sandbox, by a grading user that is not root: the
kernel's count, ``RLIMIT_NPROC``, would then count all of that user's processes), it kills a run that has
more processes and threads at once than its limit, which then ends as ``processes``.  It also keeps the
run's CPU time and how long its threads waited for a CPU (:attr:`Watchdog.cpu_seconds`,
:attr:`Watchdog.waited_seconds`), which say of a run killed at its wall time whether the machine was busy.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from .usage import FILE_BYTES, Shares, folders, mapping_bytes, open_files
from .usage import family as _family

#: seconds between two looks at a run, and every how many looks it also reads the run's CPU time
INTERVAL, USAGE_EVERY = 0.1, 5


def family(root: int) -> dict[int, int]:
    """``root`` and every process descended from it, each with its number of threads."""
    return _family(root).threads


class Watchdog:
    """Looks after one run (:meth:`start` once its command has started, :meth:`stop` once it has ended):
    ``exceeded`` is then the limit it killed the run for (``memory``, ``processes``) or None."""

    name = "the watchdog"

    def __init__(self, memory_bytes: int, processes: int | None, interval: float = INTERVAL, most: int = 64):
        """``processes``: the run's processes and threads, where the watchdog counts them; ``most``: the most
        processes the run may have however they are counted (the deepest its forks go: what each of its
        mappings costs the kernel, :func:`~service.programs.usage.mapping_bytes`)."""
        self.memory_bytes, self.processes, self.interval = memory_bytes, processes, interval
        self.exceeded: str | None = None
        self.peak = 0
        self.cpu_seconds = 0.0
        self.waits: dict[int, float] = {}
        self.inside: int | None = None
        self.shares = Shares(mapping=mapping_bytes(most))
        self.looks = 0
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._pid: int | None = None
        self._thread: threading.Thread | None = None

    @property
    def waited_seconds(self) -> float:
        """How long the run's threads waited, ready, for a CPU (those seen, each at its last look)."""
        return sum(self.waits.values())

    def start(self, pid: int, kill: Callable[[], None], inside: int | None = None) -> None:
        """Look at the run whose command is ``pid`` (``inside``: its sandbox's first process) until it ends."""
        self.inside, self._pid = inside, pid

        def watch() -> None:
            while not self._stop.wait(self.interval):
                with self._lock:
                    self.exceeded = self.look(pid)
                if self.exceeded is not None:
                    kill()
                    return

        self._thread = threading.Thread(target=watch, name="phongray-watchdog", daemon=True)
        self._thread.start()

    def look(self, pid: int, walk: bool = False) -> str | None:
        """One look at the run whose command is ``pid``: the limit it is over, or None (``walk``: its pages'
        shares walked now, if over the cheap bound, whatever the walks' budget)."""
        self.looks += 1
        found = _family(pid, usage=self.looks % USAGE_EVERY == 1)
        self.cpu_seconds = max(self.cpu_seconds, found.cpu_seconds)
        self.waits.update(found.waits or {})
        pids = list(found.threads)
        if self.processes is not None and sum(found.threads.values()) > self.processes:
            return "processes"
        held = open_files(pids) * FILE_BYTES + folders(self.inside)
        pages, exact = self.shares.pages(pids, self.memory_bytes - held, walk)
        self.peak = max(self.peak, held + pages)
        over = held > self.memory_bytes or (exact and held + pages > self.memory_bytes)
        return "memory" if over else None

    def last_look(self) -> None:
        """At the wall-time limit, before the kill: one look with a walk, so that a run then over a limit ends
        for it, not for its time, however late a busy machine let the looks before come."""
        if self._pid is None:
            return
        with self._lock:
            if self.exceeded is None:
                self.exceeded = self.look(self._pid, walk=True)

    def stop(self) -> str | None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        return self.exceeded

    def close(self) -> None:
        """Nothing to remove (a cgroup's group has)."""
