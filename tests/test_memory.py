"""When memory goes back to the OS (tracer/memory.py)."""

import mmap
import subprocess
import sys

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


ONE_ARENA_PROBE = """
import sys, threading
import numpy as np
from tracer import memory
memory.tune_allocator(arenas=int(sys.argv[1]))
before = memory.resident()
def render_like():  # 90 MiB of chunk-sized arrays on a pool thread: more than one 64 MiB arena heap
    arrays = [np.ones((65536, 3)) for _ in range(60)]
    del arrays
worker = threading.Thread(target=render_like)
worker.start()
worker.join()
grown = memory.resident() - before
memory.release()
print(grown >> 20, (memory.resident() - before) >> 20)
"""


def test_with_one_arena_a_pool_threads_freed_memory_all_goes_back():
    """The service's setting (service.http.app): what a render thread freed is handed back in full by release()."""
    out = subprocess.run([sys.executable, "-c", ONE_ARENA_PROBE, "1"], capture_output=True, text=True, check=True)
    grown, kept = map(int, out.stdout.split())
    assert grown >= 80, out.stdout  # the arrays were resident ...
    assert kept < 8, out.stdout  # ... and are not after the release


IMPORT_PROBE = """
import schemas
import tracer
from tracer import memory
assert not memory.tuned(), "importing the tracer tuned the allocator"
data = {"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0]}, "image": {"width": 2, "height": 2}}
tracer.Renderer(schemas.validate_scene(data))
assert memory.tuned(), "the first renderer did not tune it"
"""

TUNED_PROBE = """
import schemas
import tracer
from tracer import memory
memory.tune_allocator(arenas=1)
def again(arenas=0):
    raise AssertionError("a renderer tuned the allocator again over the process's own settings")
memory.tune_allocator = again
data = {"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0]}, "image": {"width": 2, "height": 2}}
tracer.Renderer(schemas.validate_scene(data)).pixels()
"""


def test_importing_the_tracer_changes_no_setting_and_a_process_own_tuning_stands():
    for probe in (IMPORT_PROBE, TUNED_PROBE):
        done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
