"""Keep freed NumPy buffers in the process, and hand them back to the OS only when it pays.

A render allocates and frees the same large arrays chunk after chunk.  With
glibc's defaults each one is a fresh ``mmap`` whose pages fault in one by one,
which costs as much as the arithmetic: :func:`tune_allocator` raises the mmap
and trim thresholds so that the allocator reuses the memory.  Importing the
tracer changes nothing; a process's first renderer tunes it (:func:`tune_once`)
unless the process tuned it already (a service, for one arena).  A long-running
service gives memory back only after a render that made the process grow
(:func:`release_if_grown`): memory handed back must fault its pages in again
on the next render.  Elsewhere (not glibc) this does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import threading

M_TRIM_THRESHOLD, M_TOP_PAD, M_MMAP_THRESHOLD, M_ARENA_MAX = -1, -2, -3, -8


def _libc() -> ctypes.CDLL | None:
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        return ctypes.CDLL(name)
    except OSError:
        return None


#: a render that leaves the process this much larger hands its freed memory back (:func:`release_if_grown`)
GROWTH = 16 << 20


def resident() -> int | None:
    """This process's resident size in bytes (Linux), or None where it cannot be read."""
    try:
        with open("/proc/self/statm", "rb") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def release_if_grown(before: int | None) -> None:
    """:func:`release` when the process grew by :data:`GROWTH` since ``before`` (or its size is unknown).

    Small renders leave their freed memory to the allocator, which hands it
    to the next render: giving it back to the OS each time made every render
    fault its pages in again (on a VM, 20 ms of a 50 ms request)."""
    now = resident()
    if before is None or now is None or now - before >= GROWTH:
        release()


def release() -> None:
    """Hand the memory a finished render freed back to the OS (a long-running service calls this)."""
    libc = _libc()
    trim = getattr(libc, "malloc_trim", None)
    if trim is not None:
        trim(0)


#: whether this process tuned its allocator, and the lock that makes it once
_tuned, _tuning = False, threading.Lock()


def tune_once() -> None:
    """:func:`tune_allocator` with its defaults, the first time a process renders, unless it was tuned already."""
    with _tuning:
        if not _tuned:
            tune_allocator()


def tuned() -> bool:
    """Whether this process tuned its allocator (:func:`tune_allocator`)."""
    return _tuned


def tune_allocator(arenas: int = 0) -> bool:
    """Returns True when the allocator accepted the settings.

    ``arenas`` caps glibc's malloc arenas (0: two per core).  A process that
    must hand memory back after each large render (the service) asks for
    one, before it starts any thread: ``malloc_trim`` returns the free top of
    the main heap but not always that of a thread's arena, which can keep up
    to one 64 MiB heap per arena resident after the render that grew it."""
    global _tuned
    _tuned = True
    mallopt = getattr(_libc(), "mallopt", None)
    if mallopt is None:
        return False
    ok = mallopt(M_MMAP_THRESHOLD, 256 << 20) == 1
    ok &= mallopt(M_TRIM_THRESHOLD, 512 << 20) == 1
    ok &= mallopt(M_TOP_PAD, 64 << 20) == 1
    # by default two arenas per core, not one per thread: each idle arena would keep its pages
    ok &= mallopt(M_ARENA_MAX, arenas or 2 * (os.cpu_count() or 1)) == 1
    return bool(ok)
