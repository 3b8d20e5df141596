"""A run's memory and processes are its own (service.programs.guard): the memory of all its processes together
is held to the limit, and its processes are counted apart from every other run's and from the grading user's
own, whoever runs phongray.

Runs of a grading user that is not root all run as that user; as root each run has a user of its own.  The
tests that are about a shared user make every run of theirs one user when they are run as root (a sandbox's
user drawn for the test), so that they test what a teaching assistant's account would meet."""

import os
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time

import pytest
from test_programs import PRELUDE, make_course, nothing_left  # noqa: F401  (after every test: nothing of a run left)

from service.programs import Limits, ProgramRun, Reason, run_program
from service.programs.guard import enforcement
from service.programs.outcome import busy
from service.programs.process import Command, run_command
from service.programs.sandbox import sandbox_uid
from service.programs.watchdog import Watchdog, family

#: four children touching 200 MB each and holding it: each within the 512 MiB limit, together far over it
FOUR_CHILDREN = """\
    kids = []
    for _ in range(4):
        pid = os.fork()
        if pid == 0:
            block = bytearray(200 << 20)
            for i in range(0, len(block), 4096):
                block[i] = 1
            time.sleep(10)
            os._exit(0)
        kids.append(pid)
    for pid in kids:
        os.waitpid(pid, 0)
    write_png(output)
    """
#: forks children until the process limit refuses one, and holds them all
QUOTA_HOLDER = """\
    made = 0
    try:
        while made < 500:
            if os.fork() == 0:
                time.sleep(60)
                os._exit(0)
            made += 1
    except OSError:
        pass
    print("HOLDING", made, file=sys.stderr, flush=True)
    time.sleep(60)
    """


@pytest.fixture
def course(tmp_path):
    """The TA's scene and a class of two students (test_programs.py's)."""
    return make_course(tmp_path)


def run(root, body: str, limits: Limits):
    folder = root / "subs" / "ann"
    (folder / "render.py").write_text(PRELUDE + textwrap.dedent(body))
    command = "python3 render.py {scene} {output}"
    return run_program(ProgramRun(folder, command, root / "scenes" / "spheres.json", limits))


@pytest.fixture
def shared_user(monkeypatch):
    """The one user every run of the test is, as a grading user's runs are: this process's own, or (as root)
    a sandbox's user drawn for the test; with :func:`start_as` to run more processes as it."""
    if os.geteuid() != 0:
        return os.getuid()
    uid = sandbox_uid()
    monkeypatch.setattr("service.programs.runner.sandbox_uid", lambda: uid)
    return uid


def start_as(uid: int, argv: list[str]) -> subprocess.Popen:
    prefix = [] if os.geteuid() != 0 else ["setpriv", f"--reuid={uid}", f"--regid={uid}", "--clear-groups", "--"]
    return subprocess.Popen([*prefix, *argv], start_new_session=True)


def test_four_children_over_the_memory_budget_end_the_run_as_memory(course):
    outcome = run(course, FOUR_CHILDREN, Limits(memory_bytes=512 << 20, wall_seconds=60.0))
    assert outcome.reason is Reason.MEMORY, (outcome.reason, outcome.detail, outcome.stderr_tail[-500:])
    assert outcome.detail.startswith("ran out of memory (limit 512 MiB, its processes together, held by ")


def test_children_sharing_their_parents_pages_count_them_once(course):
    """An honest program that forks workers over one 300 MB array (shared until written): five processes that
    each show 300 MB resident, 300 MB together, within a 512 MiB limit."""
    body = """\
        block = bytearray(300 << 20)
        for i in range(0, len(block), 4096):
            block[i] = 1
        kids = []
        for _ in range(4):
            pid = os.fork()
            if pid == 0:
                total = sum(block[::4096])
                time.sleep(1.5)
                os._exit(0 if total == len(block) // 4096 else 1)
            kids.append(pid)
        print("CHILDREN", [os.waitpid(pid, 0)[1] for pid in kids], file=sys.stderr)
        write_png(output)
        """
    outcome = run(course, body, Limits(memory_bytes=512 << 20, wall_seconds=60.0))
    assert outcome.reason is Reason.OK, (outcome.detail, outcome.stderr_tail[-500:])
    assert "CHILDREN [0, 0, 0, 0]" in outcome.stderr_tail


def test_the_way_in_force_is_named():
    said = enforcement().describe()
    assert said.startswith("each run's memory") and ("cgroup of its own" in said or "watchdog" in said)


def test_the_grading_users_own_processes_do_not_stop_a_run(course, shared_user):
    """A grading user already running 70 processes and threads starts a run limited to 64."""
    sleeps = [start_as(shared_user, ["sleep", "600"]) for _ in range(70)]
    try:
        outcome = run(course, "write_png(output)\n", Limits(processes=64, wall_seconds=30.0))
    finally:
        for proc in sleeps:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert outcome.reason is Reason.OK, (outcome.detail, outcome.stderr_tail[-500:])


def test_a_run_holding_its_process_quota_leaves_the_next_run_its_own(course, shared_user):
    limits = Limits(processes=32, wall_seconds=20.0)
    held: list = []
    holder = threading.Thread(target=lambda: held.append(run(course, QUOTA_HOLDER, limits)))
    holder.start()
    deadline = time.monotonic() + 60  # (a bound on a hang, not a budget)
    while sum(family(os.getpid()).values()) < 30 and holder.is_alive() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert holder.is_alive()  # it holds its quota now
    other = course / "subs" / "bob"
    (other / "render.py").write_text(PRELUDE + "write_png(output)\n")
    command = "python3 render.py {scene} {output}"
    outcome = run_program(ProgramRun(other, command, course / "scenes" / "spheres.json", limits))
    holder.join()
    assert outcome.reason is Reason.OK, (outcome.detail, outcome.stderr_tail[-500:])
    assert held[0].reason is Reason.TIMEOUT
    made = int(held[0].stderr_tail.split("HOLDING ")[1].split()[0])
    assert 20 < made < 32  # its own quota, all of it, and no more


def test_the_watchdog_counts_processes_where_the_kernel_does_not(tmp_path):
    """Without the sandbox, a grading user that is not root has no count of a run's own: the watchdog counts
    the run's processes and threads, and is over a limit of 5 with 1 + 8."""
    family_of_nine = subprocess.Popen(
        ["python3", "-c", "import os, time\nfor _ in range(8):\n    os.fork() or time.sleep(60)\ntime.sleep(60)"],
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 60
        while len(family(family_of_nine.pid)) < 9 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert Watchdog(1 << 40, 5).look(family_of_nine.pid) == "processes"
        assert Watchdog(1 << 40, 64).look(family_of_nine.pid) is None
        assert Watchdog(1 << 20, None).look(family_of_nine.pid) == "memory"  # (9 Pythons hold more than 1 MiB)
    finally:
        os.killpg(family_of_nine.pid, signal.SIGKILL)
        family_of_nine.wait()


def test_a_run_over_its_memory_at_its_wall_time_ends_for_memory(tmp_path):
    """A watchdog whose looks a busy machine put off (here: none in the hour) looks once more when the run's
    wall time is up, before the kill: four children holding 200 MB each end the run as ``memory``, not
    ``timeout``, as they would have on an idle machine."""
    script = textwrap.dedent(FOUR_CHILDREN).replace("write_png(output)", "")
    argv = [sys.executable, "-c", "import os, time\n" + script]
    guard = Watchdog(512 << 20, None, interval=3600)
    command = Command(argv, str(tmp_path), dict(os.environ), 3.0, 0, 4096, guard=guard)
    finished = run_command(command)
    assert (finished.exceeded, finished.timed_out) == ("memory", False)
    assert guard.looks == 1


def test_a_run_killed_at_its_wall_time_says_whether_it_waited_for_a_cpu(course):
    """Three processes that spin on one CPU wait, ready, for it twice as long as they run: a run timed out that way
    was not given the CPU it asked for, and the TA is told so (as a busy grading machine would make it)."""
    body = """\
        os.sched_setaffinity(0, {0})
        for _ in range(2):
            if os.fork() == 0:
                break
        while True:
            pass
        """
    outcome = run(course, body, Limits(wall_seconds=3.0, cpu_seconds=60))
    assert outcome.reason is Reason.TIMEOUT, (outcome.reason, outcome.detail)
    assert outcome.waited_seconds > outcome.cpu_seconds >= 0.5, (outcome.waited_seconds, outcome.cpu_seconds)
    said = busy(outcome) or ""
    ran, waited = (float(w) for w in re.findall(r"having run ([\d.]+) s and waited ([\d.]+) s for a CPU", said)[0])
    assert (ran, waited) == (round(outcome.cpu_seconds, 1), round(outcome.waited_seconds, 1))
    assert "the grading machine was busy" in said
    assert outcome.detail == "still running at the wall-time limit of 3 s; killed"  # (the same however busy)


@pytest.mark.parametrize(
    "said, reason",
    [
        # Node's words, in its own case: a write past the file-size limit, an allocation refused
        ("Error: EFBIG: file too large, write\n    at Object.writeSync (node:fs:927:3)\n", Reason.OUTPUT_TOO_LARGE),
        ("RangeError: Array buffer allocation failed\n    at new ArrayBuffer (<anonymous>)\n", Reason.MEMORY),
        ("Fatal process OOM in Failed to reserve virtual memory for CodeRange\n", Reason.MEMORY),
        ("Traceback (most recent call last):\nMemoryError\n", Reason.MEMORY),
        ("OSError: [Errno 27] File too large\n", Reason.OUTPUT_TOO_LARGE),
        ("TypeError: cannot read properties of undefined\n", Reason.CRASHED),
    ],
)
def test_a_runtimes_own_words_for_a_limit_name_the_limit(said, reason):
    """A program that dies of a limit in its runtime's own words (Node's lower-case ``EFBIG``, its array
    buffers) is told as that limit, not as a crash."""
    from service.programs.outcome import failure
    from service.programs.process import Finished

    finished = Finished(1 << 8, False, False, b"", said.encode(), 0.1, 0.1)
    assert failure(finished, Limits()) is not None
    assert failure(finished, Limits())[0] is reason
