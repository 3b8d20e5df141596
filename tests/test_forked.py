"""`phongray render` of a large image forks a process per core (service.render.rendering.render_forked): the processes
die with the parent, whatever signal reaches it alone, and a process killed mid-render is one line, exit 1."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from helpers import scene_dict

#: seconds any wait here may take: the product has no deadline of its own for these, so a generous bound
PATIENCE = 60.0


def children(pid: int) -> set[int]:
    """The processes whose parent is ``pid`` (from /proc; the kernel lists them per thread)."""
    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out.update(int(p) for p in (task / "children").read_text().split())
        except OSError:
            pass
    return out


def alive(pid: int) -> bool:
    """Whether ``pid`` still runs (a zombie, dead but not yet reaped, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except OSError:
        return False


def start_forked_render(tmp_path: Path) -> tuple[subprocess.Popen, set[int]]:
    """A render large enough to run over forked processes for many seconds, and its processes once both run."""
    data = scene_dict("03_soft_shadows")
    data["image"].update(width=1920, height=1080, samples=4)
    scene = tmp_path / "big.json"
    scene.write_text(json.dumps(data))
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "service.cli",
            "render",
            str(scene),
            "-o",
            str(tmp_path / "big.png"),
            "--threads",
            "2",
            "-q",
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + PATIENCE
    while len(children(proc.pid)) < 2:
        assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
        assert time.monotonic() < deadline, "the render never forked its processes"
        time.sleep(0.05)
    return proc, children(proc.pid)


def wait_gone(pids: set[int]) -> set[int]:
    """The ``pids`` still running after up to :data:`PATIENCE` seconds."""
    deadline = time.monotonic() + PATIENCE
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    return {p for p in pids if alive(p)}


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_the_forked_processes_die_with_their_parent(tmp_path, sig):
    proc, forked = start_forked_render(tmp_path)
    try:
        os.kill(proc.pid, sig)  # to the parent alone, as a supervisor's `kill PID` or subprocess's timeout does
        proc.wait(timeout=PATIENCE)
        assert wait_gone(forked) == set()
    finally:
        for pid in forked:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
        proc.stderr.close()


def test_a_forked_process_killed_mid_render_is_one_line_and_exit_1(tmp_path):
    proc, forked = start_forked_render(tmp_path)
    victim = min(forked)
    os.kill(victim, signal.SIGKILL)  # as the OOM killer would
    try:
        _, err = proc.communicate(timeout=PATIENCE)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1
    assert err.count("\n") == 1 and "Traceback" not in err and "BrokenProcessPool" not in err, err
    assert err.startswith("phongray: ") and "a process rendering part of the image died" in err
    assert wait_gone(forked) == set() and not (tmp_path / "big.png").exists()
