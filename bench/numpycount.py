"""Counting NumPy's array allocations, for :mod:`bench.profile`: how many arrays each stage of a render makes.

Every NumPy operation that makes an array (a ufunc without ``out=``, a gather, ``np.where``, a copy) asks
NumPy's memory handler for its data; views and in-place operations do not.  So the count of allocations is
the count of passes over the data that make a new array, and their bytes the memory those passes write: the
two numbers "fewer, larger passes" lowers.

NumPy (1.22 and later) lets a program install its own handler (NEP 49).  :class:`AllocationCounter` installs
one through ``ctypes`` that forwards every call to NumPy's default handler and, for each allocation, calls
back into Python with its size.  The handler is a context variable: it counts in the thread that installs it
(the profile renders on one thread).  Where the C API is not as expected, :func:`counter` returns None and
the profile leaves the column empty.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from typing import Any

import numpy as np

_MALLOC = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)
_CALLOC = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_size_t)
_REALLOC = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)
_FREE = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)


class _Allocator(ctypes.Structure):
    _fields_ = [
        ("ctx", ctypes.c_void_p),
        ("malloc", _MALLOC),
        ("calloc", _CALLOC),
        ("realloc", _REALLOC),
        ("free", _FREE),
    ]


class _Handler(ctypes.Structure):
    _fields_ = [("name", ctypes.c_char * 127), ("version", ctypes.c_uint8), ("allocator", _Allocator)]


#: every counter made: kept for the life of the process (see AllocationCounter)
_KEPT: list[AllocationCounter] = []
#: the indices of PyDataMem_SetHandler and PyDataMem_DefaultHandler in NumPy's C-API table (stable since 1.22)
_SET_HANDLER, _DEFAULT_HANDLER = 304, 306


def _api_table() -> Any:
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:  # NumPy 1.x
        from numpy.core import _multiarray_umath as umath  # type: ignore[no-redef]
    get = ctypes.pythonapi.PyCapsule_GetPointer
    get.restype, get.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
    return ctypes.cast(get(umath._ARRAY_API, None), ctypes.POINTER(ctypes.c_void_p))


class AllocationCounter:
    """While installed (``with``), calls ``on_allocation(nbytes)`` for every array allocation of this thread."""

    def __init__(self, on_allocation: Callable[[int], None]):
        table = _api_table()
        get = ctypes.pythonapi.PyCapsule_GetPointer
        default_capsule = ctypes.cast(table[_DEFAULT_HANDLER], ctypes.POINTER(ctypes.py_object)).contents.value
        base = ctypes.cast(get(default_capsule, b"mem_handler"), ctypes.POINTER(_Handler)).contents.allocator
        ctx = base.ctx
        # NumPy may allocate with the GIL released; the callbacks take it, and call on without releasing it
        # again (a PYFUNCTYPE call: a CFUNCTYPE one would release a GIL this thread may not own)
        base_malloc = ctypes.PYFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)(
            ctypes.cast(base.malloc, ctypes.c_void_p).value
        )
        base_calloc = ctypes.PYFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_size_t)(
            ctypes.cast(base.calloc, ctypes.c_void_p).value
        )

        def malloc(own: int, size: int) -> int:
            on_allocation(size)
            return base_malloc(own, size) or 0

        def calloc(own: int, count: int, size: int) -> int:
            on_allocation(count * size)
            return base_calloc(own, count, size) or 0

        # realloc and free are NumPy's own C functions: an array made while counting may be freed at any time
        # later, at the interpreter's exit too, when no Python callback may run
        self._callbacks = (_MALLOC(malloc), _CALLOC(calloc))
        self._handler = _Handler(
            b"phongray_bench_counter", 1, _Allocator(ctx, *self._callbacks, base.realloc, base.free)
        )
        _KEPT.append(self)  # never freed: arrays made while counting keep pointing at this handler
        new = ctypes.pythonapi.PyCapsule_New
        new.restype, new.argtypes = ctypes.py_object, [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p]
        self._name = ctypes.c_char_p(b"mem_handler")  # (the capsule keeps a pointer to its name)
        self._capsule = new(ctypes.addressof(self._handler), self._name, None)
        self._set = ctypes.PYFUNCTYPE(ctypes.py_object, ctypes.py_object)(table[_SET_HANDLER])
        self._previous: Any = None

    def __enter__(self) -> AllocationCounter:
        self._previous = self._set(self._capsule)
        return self

    def __exit__(self, *exc: object) -> None:
        self._set(self._previous)


def counter(on_allocation: Callable[[int], None]) -> AllocationCounter | None:
    """An :class:`AllocationCounter`, checked to count a fresh array, or None where it cannot be installed."""
    seen: list[int] = []
    try:
        probe = AllocationCounter(seen.append)
        with probe:
            np.empty(1000)
        if seen != [8000]:
            return None
        return AllocationCounter(on_allocation)
    except (AttributeError, ImportError, OSError, TypeError, ValueError):
        return None
