"""How a render is cut into chunks of pixels and run on threads: the chunks' sizes, and the pool that runs them.

Every pixel is computed alone (its sums are exact integers, :mod:`tracer.film`), so neither the threads nor
the chunks change a byte; they set only the speed and the memory a render holds.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from .budget import Call
from .film import UNIT_RAYS

T = TypeVar("T")
R = TypeVar("R")
#: the pixels of a chunk: their numbers (row by row from the top left), or a range of them
Pixels = np.ndarray | range

#: rays per chunk on several threads: large enough for NumPy to be efficient (and for its long loops, which let
#: go of the GIL, to outweigh the interpreter's share), small enough to bound memory.  Measured on two threads:
#: 2^16 is 12-25 % faster than 2^15 on the bench scenes, 2^17 no faster; a 4096² render then peaks at 221 MiB
#: (168 MiB at 2^15)
CHUNK_RAYS = UNIT_RAYS
#: rays per chunk on one thread, where no other thread waits for the GIL and a chunk's arrays had better stay in
#: the cache: measured on one core, 2^15 is 8-20 % faster than 2^16 (three spheres at 320×240 and at 1080p, the
#: antialiased and the soft-shadow examples), 2^14 no faster
ONE_THREAD_CHUNK_RAYS = 1 << 15


def chunking(threads: int | None, chunk_rays: int | None) -> tuple[int, int]:
    """The threads a render runs on (every core by default) and the rays of its chunks."""
    workers = threads or os.cpu_count() or 1
    return workers, chunk_rays or (CHUNK_RAYS if workers > 1 else ONE_THREAD_CHUNK_RAYS)


@dataclass(frozen=True)
class Run:
    """How one render runs: on ``workers`` threads, ``per_chunk`` pixels a chunk (their sub-samples at most the
    chunk's rays), its ray trees traced in slices of at most ``slice_rays`` rays.  The call's own, so that one
    renderer may serve calls of different sizes at once."""

    workers: int
    per_chunk: int
    slice_rays: int
    call: Call  # its count and its stop (:class:`tracer.budget.Calls`)


def parts_of(pixel: Pixels, per_chunk: int) -> list[Pixels]:
    """``pixel`` cut into chunks of at most ``per_chunk`` pixels, in order.  A ``range`` of pixels stays a
    range, chunk by chunk: a whole image's pixel numbers are never held at once (as int64 they would be 8 bytes
    a pixel, more than the 3 of the image itself); :func:`pixel_numbers` makes a chunk's when it is traced."""
    return [pixel[a : a + per_chunk] for a in range(0, len(pixel), per_chunk)]


def pixel_numbers(part: Pixels) -> np.ndarray:
    """The pixel numbers of a chunk, as int64."""
    return np.arange(part.start, part.stop, dtype=np.int64) if isinstance(part, range) else part


def ordered(work: Callable[[T], R], parts: list[T], workers: int) -> Iterable[R]:
    """``work`` of every part, in order: on a pool of up to ``workers`` threads, at most ``workers`` parts begun
    beyond the one handed on (so that results wait for their turn a few at a time), or here when one would do."""
    if workers <= 1 or len(parts) <= 1:
        yield from (work(part) for part in parts)
        return
    with ThreadPoolExecutor(max_workers=min(workers, len(parts))) as pool:
        todo = iter(parts)
        pending: deque[Future[R]] = deque(pool.submit(work, part) for _, part in zip(range(workers), todo))
        while pending:
            result = pending.popleft().result()
            for part in todo:  # (the next part, if any)
                pending.append(pool.submit(work, part))
                break
            yield result
