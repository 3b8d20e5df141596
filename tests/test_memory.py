"""When memory goes back to the OS (tracer/memory.py)."""

import mmap

import numpy as np

from tracer import memory


def test_resident_size_is_read_and_follows_an_allocation():
    before = memory.resident()
    assert before is not None and before > 10 << 20
    # 64 MiB of fresh pages, touched: mapped directly, since the tuned allocator may hand out heap memory
    # that earlier tests freed and that is resident already
    block = mmap.mmap(-1, 64 << 20)
    np.frombuffer(block, dtype=np.uint8)[:] = 1
    assert memory.resident() - before > 48 << 20
    block.close()


def test_release_only_after_growth(monkeypatch):
    calls = []
    monkeypatch.setattr(memory, "release", lambda: calls.append(1))
    now = memory.resident()
    memory.release_if_grown(now)  # no growth: memory stays with the allocator for the next render
    assert calls == []
    memory.release_if_grown(now - memory.GROWTH)  # grown by the threshold: handed back
    assert calls == [1]
    memory.release_if_grown(None)  # size unknown: handed back, to be safe
    assert calls == [1, 1]
