"""Keep freed NumPy buffers in the process instead of handing them back to the OS.

A render allocates and frees the same large arrays chunk after chunk.  With
glibc's defaults each one is a fresh ``mmap`` whose pages fault in one by one,
which costs as much as the arithmetic.  Raising the mmap and trim thresholds
lets the allocator reuse the memory.  Elsewhere (not glibc) this does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

M_TRIM_THRESHOLD, M_TOP_PAD, M_MMAP_THRESHOLD, M_ARENA_MAX = -1, -2, -3, -8


def _libc() -> ctypes.CDLL | None:
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        return ctypes.CDLL(name)
    except OSError:
        return None


def release() -> None:
    """Hand the memory a finished render freed back to the OS (a long-running service calls this)."""
    libc = _libc()
    trim = getattr(libc, "malloc_trim", None)
    if trim is not None:
        trim(0)


def tune_allocator() -> bool:
    """Returns True when the allocator accepted the settings."""
    mallopt = getattr(_libc(), "mallopt", None)
    if mallopt is None:
        return False
    ok = mallopt(M_MMAP_THRESHOLD, 256 << 20) == 1
    ok &= mallopt(M_TRIM_THRESHOLD, 512 << 20) == 1
    ok &= mallopt(M_TOP_PAD, 64 << 20) == 1
    # two arenas per core, not one per thread: the service validates and renders on pool threads, and each idle
    # arena would keep its pages
    ok &= mallopt(M_ARENA_MAX, 2 * (os.cpu_count() or 1)) == 1
    return bool(ok)
