"""What a run holds, read from ``/proc`` (:mod:`service.programs.watchdog` looks with it): its processes, the
memory of their pages, what their open files and its tmpfs folders hold in the kernel, and its CPU time.

* **Pages.** A process's private pages and its share of those it shares (anonymous and shared memory, not
  the files it maps, which the kernel can drop), and its page tables (``VmPTE``).  The share (the kernel's
  ``Pss``) costs a walk of the process's page tables, so the cheap upper bound, each process's resident
  pages counted in full (``RssAnon`` + ``RssShmem``), is used while it is within the limit; past it
  :class:`Shares` walks the processes, spending at most :data:`FRACTION` of one CPU on it however many
  processes and mappings the run makes.
* **Mappings.** Each mapping (VMA) of a process is the kernel's memory, in none of its pages: a process may
  make 65,530 (``vm.max_map_count``) of a page each, and a fork copies them all, so a run of 40 processes
  held 557 MiB of the kernel's (measured: ~220 bytes a mapping, ~330 with pages written, and ~36 bytes more a
  mapping for each fork between it and its first process, whose pages it links).  Each mapping counts
  :func:`mapping_bytes` (``MAPPING_BYTES`` and ``FORK_BYTES`` for each process the run may have, the deepest
  chain of forks it can make: 4.6 KiB at the default 64, 0.7 MiB for a Python with NumPy's ~150).  The cheap
  bound is a mapping a page of the process's address space (``VmSize``, one more for the page the kernel
  shows and is not in it); past the limit a walk also counts them (the lines of ``/proc/<pid>/maps``: ~45 ms
  for 60,000 mappings, within the walks' :data:`FRACTION`).  ``RLIMIT_AS`` bounds none of this: a mapping
  of a page, none of it touched, costs the kernel its ~220 bytes for 4 KiB of address space.
* **Open files.** The buffers of a socket or a pipe are the kernel's, in no process's pages; each open file of
  the run counts :data:`FILE_BYTES`, the most one holds in the sandbox (where a socket keeps the kernel's
  default buffers and a pipe its 64 KiB: :mod:`service.programs.seccomp`), whatever it is.
* **tmpfs folders.** What the sandbox's ``/tmp``, ``/dev/shm`` and working folder hold (their used bytes,
  files deleted but still open included) and :data:`INODE_BYTES` for each of their files and folders (an
  empty file costs the kernel an inode and a name, about 1 KiB measured; a hard link counts as one).
* **CPU.** The CPU time of the run's processes (``utime`` + ``stime`` of each, and ``cutime`` + ``cstime``:
  those of the processes it reaped), and the time their threads waited, ready, for a CPU (``schedstat``):
  a run that waited most of its wall time was on a busy machine.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass

KIB = 1024
#: the kernel's fields (in kB) of a process's resident memory that count, cheap and precise; and its page tables
CHEAP = ("RssAnon", "RssShmem")
PRECISE = ("Pss_Anon", "Pss_Shmem")
TABLES = ("VmPTE",)
#: what a mapping costs the kernel at most, and more for each fork between it and its first process (see the
#: module: measured ~330 and ~36 bytes); a mapping is at least a page, and the kernel shows one that is not in
#: a process's ``VmSize`` (x86-64's ``[vsyscall]``)
MAPPING_BYTES, FORK_BYTES, PAGE, UNSIZED = 512, 64, 4 * KIB, 1
#: the sandbox's tmpfs folders, where a program writes (:mod:`service.programs.sandbox`)
FOLDERS = ("/tmp", "/dev/shm", "/home/student")
#: what each file or folder of a tmpfs costs besides its bytes (an inode and a name: ~1 KiB measured, a long
#: name more)
INODE_BYTES = 2 * KIB
#: the most of one CPU's time the watchdog spends walking a run's page tables (``smaps_rollup``), and how
#: old the last walk may be before another (when the run's resident pages are over its limit)
FRACTION, REFRESH = 0.2, 1.0


def _buffer_default(name: str) -> int:
    try:
        with open(f"/proc/sys/net/core/{name}") as f:
            return int(f.read())
    except (OSError, ValueError):
        return 212992  # (Linux's default)


#: the most an open file holds in the kernel in the sandbox: a socket twice its default buffer (what it has
#: queued, and one more packet of up to the buffer's size; ``net.core.wmem_default`` and ``rmem_default``),
#: and 64 KiB of slack for the kernel's own structures; a pipe (64 KiB) less
FILE_BYTES = 2 * max(_buffer_default("wmem_default"), _buffer_default("rmem_default")) + 64 * KIB


def read(path: str) -> str:
    try:
        with open(path) as f:
            return f.read()
    except OSError:  # (the process has ended)
        return ""


def fields(text: str, names: tuple[str, ...]) -> int:
    """The sum of the named fields (kB) of a /proc file, in bytes."""
    total = 0
    for line in text.splitlines():
        name, _, rest = line.partition(":")
        if name in names:
            total += int(rest.split()[0]) * KIB
    return total


@dataclass
class Family:
    """The run's processes at one look: each with its number of threads, and the run's CPU time in that
    look (its live processes', with what they reaped) and what its live threads have waited for a CPU."""

    threads: dict[int, int]
    cpu_seconds: float = 0.0
    waits: dict[int, float] | None = None


def _cpu(pid: int) -> float:
    """A process's CPU time and that of the processes it reaped (``/proc/<pid>/stat``), in seconds."""
    text = read(f"/proc/{pid}/stat")
    rest = text[text.rfind(")") + 2 :].split()  # (after the command's name, which may hold anything)
    try:
        return sum(int(n) for n in rest[11:15]) / os.sysconf("SC_CLK_TCK")
    except (ValueError, IndexError):
        return 0.0


def _waited(pid: int, tid: str) -> float:
    """Seconds a thread has waited, ready, for a CPU (the second field of its ``schedstat``, in ns)."""
    try:
        return int(read(f"/proc/{pid}/task/{tid}/schedstat").split()[1]) / 1e9
    except (ValueError, IndexError):
        return 0.0


def family(root: int, usage: bool = False) -> Family:
    """``root`` and every process descended from it, each with its number of threads (read from each
    thread's ``children``: a process a thread started is that thread's child); with ``usage``, their CPU
    time and each thread's wait for a CPU too."""
    found = Family({}, waits={} if usage else None)
    todo = [root]
    while todo:
        pid = todo.pop()
        if pid in found.threads:
            continue
        try:
            threads = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        found.threads[pid] = len(threads)
        if found.waits is not None:
            found.cpu_seconds += _cpu(pid)
        for tid in threads:
            todo.extend(int(child) for child in read(f"/proc/{pid}/task/{tid}/children").split())
            if found.waits is not None:
                found.waits[int(tid)] = _waited(pid, tid)
    return found


def open_files(pids: list[int]) -> int:
    """How many files the processes hold open (their descriptors; threads share their process's)."""
    total = 0
    for pid in pids:
        try:
            total += len(os.listdir(f"/proc/{pid}/fd"))
        except OSError:
            continue
    return total


def folders(inside: int | None) -> int:
    """What the sandbox's tmpfs folders hold, in bytes (their used blocks, and :data:`INODE_BYTES` a file or
    folder), seen through the root of ``inside``, a process of the sandbox; 0 without one, and 0 while its root
    is still the machine's: bubblewrap names its first process as soon as it is cloned, before it has made its
    own root, and until then ``/tmp`` there is the machine's, whose used blocks (gigabytes of a disk) are no run's
    (a look that came first, on a busy machine, ended a run of a few bytes as out of memory)."""
    if inside is None or _same_root(inside):
        return 0
    total = 0
    for folder in FOLDERS:
        try:
            seen = os.statvfs(f"/proc/{inside}/root{folder}")
        except OSError:
            continue
        total += (seen.f_blocks - seen.f_bfree) * seen.f_frsize + (seen.f_files - seen.f_ffree) * INODE_BYTES
    return total


def _same_root(pid: int) -> bool:
    """Whether process ``pid``'s root is this one's (or it has ended): not yet, or never, a sandbox's own."""
    try:
        theirs, ours = os.stat(f"/proc/{pid}/root/"), os.stat("/")
    except OSError:
        return True
    return (theirs.st_dev, theirs.st_ino) == (ours.st_dev, ours.st_ino)


def mapping_bytes(processes: int) -> int:
    """What a mapping counts in a run of at most ``processes`` processes (see the module)."""
    return MAPPING_BYTES + FORK_BYTES * processes


def _cheap(pid: int) -> tuple[int, int, int]:
    """A process's resident pages (the cheap bound), its page tables, both in bytes, and the most mappings it
    can have (a page of its address space each); all 0 for a process that has ended."""
    status = read(f"/proc/{pid}/status")
    size = fields(status, ("VmSize",))
    return fields(status, CHEAP), fields(status, TABLES), size // PAGE + UNSIZED if status else 0


def _mappings(pid: int) -> int:
    """How many mappings a process has (the lines of its ``maps``, read a MiB at a time); 0 once it has ended."""
    lines = 0
    try:
        with open(f"/proc/{pid}/maps", "rb") as f:
            while chunk := f.read(1 << 20):
                lines += chunk.count(b"\n")
    except OSError:
        pass
    return lines


def _share(pid: int, resident: int) -> int:
    """A process's share of its pages (``Pss``), a walk of its page tables; ``resident`` is what it had when
    its status was read (a process that has ended since has nothing)."""
    rollup = read(f"/proc/{pid}/smaps_rollup")
    if "Pss_Anon:" in rollup:
        return fields(rollup, PRECISE)
    if rollup:  # (a kernel before 5.8 has no Pss_Anon)
        return fields(rollup, ("Pss",))
    # (no rollup: the process has ended, or the kernel would not show it: then the bound, read again now)
    return min(resident, _cheap(pid)[0])


def _walk(pid: int, resident: int) -> tuple[int, int]:
    """A process's share of its pages (:func:`_share`) and how many mappings it has, at one walk."""
    return _share(pid, resident), _mappings(pid)


class Shares:
    """The pages (and mappings) of a run's processes, each look: the cheap bound while it is within the limit.
    Past it, the processes' shares and mappings, walked all in one look (so the sum is of one moment: a
    process's share falls when it forks, and a sum of shares walked at different moments could count a page
    twice), at most a :data:`FRACTION` of the time (of one CPU): a walk is made when the estimate is over the
    limit or the last walk is :data:`REFRESH` seconds old, and the time walked is paid back before the next.
    Between walks the estimate is the last walk's shares and mappings plus what each process's resident pages
    grew since (a new process's cheap bound in full); only a walk's sum is ``exact``, what a run is killed on.
    ``mapping`` is what each mapping counts (:func:`mapping_bytes`)."""

    def __init__(
        self,
        clock: Callable[[], float] = time.monotonic,
        mapping: int = mapping_bytes(64),
        cpu: Callable[[], float] = time.thread_time,
    ):
        """``clock``: the time between looks; ``cpu``: the watchdog's own CPU time, what a walk costs (on a
        busy machine a walk can take many times its CPU time in wall time, none of it the grader's)."""
        self.clock, self.mapping, self.cpu = clock, mapping, cpu
        self.walked: dict[int, tuple[int, int, int]] = {}  # pid: (share, mappings, resident pages when walked)
        self.owed = 0.0  # seconds to wait before the next walk
        self.then = clock()
        self.last = -REFRESH

    def pages(self, pids: list[int], limit: int, walk: bool = False) -> tuple[int, bool]:
        """The pages (and page tables and mappings) of ``pids`` together, in bytes, and whether the sum is exact
        (a walk's, or the cheap bound within ``limit``) rather than the estimate between walks; ``walk``: a
        walk now if one is needed, whatever is owed (the last look of a run)."""
        seen = {pid: _cheap(pid) for pid in pids}
        tables = sum(t for _, t, _ in seen.values())
        cheap = tables + sum(r + self.mapping * most for r, _, most in seen.values())
        if cheap <= limit:
            return cheap, True
        now = self.clock()
        self.owed = max(0.0, self.owed - (now - self.then))
        self.then = now
        estimate = tables + sum(self._estimate(pid, r, most) for pid, (r, _, most) in seen.items())
        if not walk and (self.owed > 0 or (estimate <= limit and now - self.last < REFRESH)):
            return estimate, False
        used = self.cpu()
        self.walked = {pid: (*_walk(pid, r), r) for pid, (r, _, _) in seen.items()}
        spent = self.cpu() - used
        self.then, self.last = self.clock(), now
        self.owed += spent / FRACTION - spent  # (the time to wait before the next walk)
        return tables + sum(share + self.mapping * maps for share, maps, _ in self.walked.values()), True

    def _estimate(self, pid: int, resident: int, most: int) -> int:
        """A process's pages and mappings since the last walk: what it then had, and its pages' growth."""
        if pid not in self.walked:
            return resident + self.mapping * most
        share, maps, then = self.walked[pid]
        return share + max(0, resident - then) + self.mapping * maps
