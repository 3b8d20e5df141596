"""Chunks of pixels and the pool that runs them: results in order, a few chunks ahead, stopped by the first
error."""

import threading
import time

import numpy as np
import pytest

from tracer.chunks import ONE_THREAD_CHUNK_RAYS, chunking, ordered, parts_of


def test_parts_cover_the_pixels_in_order():
    pixel = np.arange(10, 33)
    parts = parts_of(pixel, 7)
    assert [len(p) for p in parts] == [7, 7, 7, 2]
    assert np.array_equal(np.concatenate(parts), pixel)
    assert parts_of(pixel[:0], 7) == []


def test_one_thread_takes_the_smaller_chunks():
    assert chunking(1, None) == (1, ONE_THREAD_CHUNK_RAYS)
    assert chunking(3, 100) == (3, 100)


def test_results_come_in_order_whatever_order_the_threads_finish_in():
    def work(k: int) -> int:
        time.sleep(0.002 * ((7 * k) % 5))
        return k * k

    assert list(ordered(work, list(range(12)), 3)) == [k * k for k in range(12)]


def test_at_most_workers_parts_run_beyond_the_one_handed_on():
    started: list[int] = []
    lock = threading.Lock()

    def work(k: int) -> int:
        with lock:
            started.append(k)
        return k

    for k in ordered(work, list(range(20)), 2):
        with lock:
            assert max(started) <= k + 2


def test_an_error_ends_the_run():
    def work(k: int) -> int:
        if k == 3:
            raise RuntimeError("stop")
        return k

    got = []
    with pytest.raises(RuntimeError):
        for k in ordered(work, list(range(50)), 2):
            got.append(k)
    assert got == [0, 1, 2]
