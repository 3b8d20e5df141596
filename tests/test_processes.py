"""The local pool's processes (service/classgrade/processes.py): forked from a forkserver, they take the grading
process's environment as it is when the pool is made, and end when the grading process is gone even though
their own parent, the forkserver, lives on."""

from __future__ import annotations

import multiprocessing
import os
import sys
import tempfile
import time
from pathlib import Path

import pytest

from service.classgrade import processes
from service.classgrade.backends import LocalBackend

#: seconds any wait here may take: the product has no deadline of its own for these, so a generous bound
PATIENCE = 60.0


def seen() -> tuple[str | None, str, int]:
    """What a pool process sees: the probe variable, its temporary folder, its parent."""
    return os.environ.get("PHONGRAY_PROBE"), tempfile.gettempdir(), os.getppid()


def test_a_pool_process_takes_the_environment_of_the_grading_process_when_the_pool_is_made(tmp_path, monkeypatch):
    first = LocalBackend(1, 1, None)
    try:  # (the forkserver now runs, with the environment it started with)
        assert first.executor is not None and first.executor.submit(seen).result()[0] is None
    finally:
        first.close()
    monkeypatch.setenv("PHONGRAY_PROBE", "set after the forkserver started")
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    second = LocalBackend(1, 1, None)
    try:
        assert second.executor is not None
        probe, temporary, parent = second.executor.submit(seen).result()
    finally:
        second.close()
    assert (probe, temporary) == ("set after the forkserver started", str(tmp_path))
    if "forkserver" in multiprocessing.get_all_start_methods():
        assert parent != os.getpid()  # (forked by the forkserver, not spawned by this process)


def sleep_in_pool(line, environ: dict[str, str], ready: Path) -> None:  # noqa: ANN001
    """A pool process's start (:func:`processes.join`), then a long task."""
    processes.join(line, environ, False)  # (no PR_SET_PDEATHSIG: the lifeline alone ends it)
    ready.write_text(str(os.getpid()))
    time.sleep(PATIENCE)


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_pool_process_ends_when_the_grading_process_is_gone_though_its_parent_lives(tmp_path):
    """The grading process's end is the end of its lifeline's writing end: here this test holds that end and
    closes it, as the kernel does for a grading process killed by SIGKILL, while the pool process's parent (the
    forkserver, or this process where there is none) still runs: a pool process that watched its parent would
    run on."""
    reading, writing = multiprocessing.Pipe(duplex=False)
    ready = tmp_path / "ready"
    process = processes.context().Process(target=sleep_in_pool, args=(reading, dict(os.environ), ready))
    process.start()
    try:
        deadline = time.monotonic() + PATIENCE
        while not ready.exists() and process.is_alive() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert ready.exists() and process.is_alive(), "the pool process did not start"
        parent = int(Path(f"/proc/{process.pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
        writing.close()
        process.join(PATIENCE)
        assert not process.is_alive(), "the pool process outlived its grading process"
        assert process.exitcode == 1
        assert _alive(parent)  # (its parent did not end it)
    finally:
        process.kill()
        process.join()
