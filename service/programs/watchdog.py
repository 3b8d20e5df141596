"""The watchdog: a run's memory (and, where nothing else counts them, its processes) held to its limits by
looking, where no cgroup of its own can be made for it (:mod:`service.programs.cgroup`).

Ten times a second it finds the run's processes (every descendant of the command phongray started: in the
sandbox, its PID namespace, whose orphans are adopted by its first process, so a daemon stays among them),
and adds up their memory; past the limit it kills the run, which then ends as ``memory``.  The memory of a
process is its private pages and its share of the pages it shares (anonymous and shared memory, not the
files it maps, which the kernel can drop): a child forked from a large process, which shares its pages
until it writes them, counts its share only.  That share (the kernel's ``Pss``) costs a walk of the
process's page tables, so it is asked only when the cheap upper bound, the resident pages of each process
counted in full (``RssAnon`` + ``RssShmem``), is over the limit.  Between two looks a run can go over the
limit for a tenth of a second; each process is also held to its address space (``RLIMIT_AS``), so no one
process goes past it.  The files a run writes in its tmpfs folders are held by their own sizes.

Where it counts processes too (a run without the sandbox, by a grading user that is not root: the
kernel's count, ``RLIMIT_NPROC``, would then count all of that user's processes), it kills a run that has
more processes and threads at once than its limit, which then ends as ``processes``.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable

#: seconds between two looks at a run
INTERVAL = 0.1
KIB = 1024
#: the kernel's fields (in kB) of a process's resident memory that count, cheap and precise
CHEAP = ("RssAnon", "RssShmem")
PRECISE = ("Pss_Anon", "Pss_Shmem")


def _read(path: str) -> str:
    try:
        with open(path) as f:
            return f.read()
    except OSError:  # (the process has ended)
        return ""


def _fields(text: str, names: tuple[str, ...]) -> int:
    """The sum of the named fields (kB) of a /proc file, in bytes."""
    total = 0
    for line in text.splitlines():
        name, _, rest = line.partition(":")
        if name in names:
            total += int(rest.split()[0]) * KIB
    return total


def family(root: int) -> dict[int, int]:
    """``root`` and every process descended from it, each with its number of threads (read from each
    thread's ``children``: a process a thread started is that thread's child)."""
    found: dict[int, int] = {}
    todo = [root]
    while todo:
        pid = todo.pop()
        if pid in found:
            continue
        try:
            threads = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        found[pid] = len(threads)
        for tid in threads:
            todo.extend(int(child) for child in _read(f"/proc/{pid}/task/{tid}/children").split())
    return found


def memory(pids: list[int], limit: int) -> int:
    """The memory of these processes together (see the module); the cheap bound when it is within
    ``limit``, else the precise sum."""
    cheap = sum(_fields(_read(f"/proc/{pid}/status"), CHEAP) for pid in pids)
    if cheap <= limit:
        return cheap
    total = 0
    for pid in pids:
        rollup = _read(f"/proc/{pid}/smaps_rollup")
        if "Pss_Anon:" in rollup:
            total += _fields(rollup, PRECISE)
        else:  # (a kernel before 5.8 has no Pss_Anon; one that would not show it, the bound)
            total += _fields(rollup, ("Pss",)) if rollup else _fields(_read(f"/proc/{pid}/status"), CHEAP)
    return total


class Watchdog:
    """Looks after one run (:meth:`start` once its command has started, :meth:`stop` once it has ended):
    ``exceeded`` is then the limit it killed the run for (``memory``, ``processes``) or None."""

    name = "the watchdog"

    def __init__(self, memory_bytes: int, processes: int | None, interval: float = INTERVAL):
        self.memory_bytes, self.processes, self.interval = memory_bytes, processes, interval
        self.exceeded: str | None = None
        self.peak = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self, pid: int, kill: Callable[[], None]) -> None:
        def watch() -> None:
            while not self._stop.wait(self.interval):
                self.exceeded = self.look(pid)
                if self.exceeded is not None:
                    kill()
                    return

        self._thread = threading.Thread(target=watch, name="phongray-watchdog", daemon=True)
        self._thread.start()

    def look(self, pid: int) -> str | None:
        """One look at the run whose command is ``pid``: the limit it is over, or None."""
        processes = family(pid)
        if self.processes is not None and sum(processes.values()) > self.processes:
            return "processes"
        used = memory(list(processes), self.memory_bytes)
        self.peak = max(self.peak, used)
        return "memory" if used > self.memory_bytes else None

    def stop(self) -> str | None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        return self.exceeded

    def close(self) -> None:
        """Nothing to remove (a cgroup's group has)."""
