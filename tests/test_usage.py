"""What a run holds beyond its processes' pages, counted to its memory (service.programs.usage): the buffers of
its sockets, what its tmpfs folders hold (bytes and files), its mappings, each process's open files bounded;
and the cost of the watchdog's walks of page tables bounded, however the run is made."""

import os
import subprocess
import textwrap
import time

import pytest
from test_programs import PRELUDE, make_course, nothing_left  # noqa: F401  (after every test: nothing of a run left)

from service.programs import Limits, ProgramRun, Reason, run_program, usage
from service.programs.limits import OPEN_FILES
from service.programs.usage import FRACTION, REFRESH, Shares

MIB = 1 << 20


@pytest.fixture
def course(tmp_path):
    """The TA's scene and a class of two students (test_programs.py's)."""
    return make_course(tmp_path)


def run(root, body: str, limits: Limits):
    folder = root / "subs" / "ann"
    (folder / "render.py").write_text(PRELUDE + textwrap.dedent(body))
    command = "python3 render.py {scene} {output}"
    return run_program(ProgramRun(folder, command, root / "scenes" / "spheres.json", limits))


#: four children, each filling 120 socketpairs both ways (each socket the kernel's default buffer) and holding them
SOCKET_HOARDERS = """\
    def hoard():
        pairs, queued = [], 0
        for _ in range(120):
            a, b = socket.socketpair()
            for s in (a, b):
                s.setblocking(False)
                try:
                    while True:
                        queued += s.send(b"y" * 65536)
                except BlockingIOError:
                    pass
            pairs.append((a, b))
        print("QUEUED", queued >> 20, "MiB", file=sys.stderr, flush=True)
        time.sleep(20)
    kids = []
    for _ in range(4):
        pid = os.fork()
        if pid == 0:
            hoard()
            os._exit(0)
        kids.append(pid)
    for pid in kids:
        os.waitpid(pid, 0)
    write_png(output)
    """


def test_what_sockets_hold_counts_to_the_runs_memory(course):
    """Data queued in sockets is the kernel's memory, in no process's pages: four processes holding 240 sockets
    each, their buffers full (about 200 MiB), are over a 256 MiB limit with what those sockets can hold."""
    outcome = run(course, SOCKET_HOARDERS, Limits(memory_bytes=256 * MIB, wall_seconds=60.0))
    assert outcome.reason is Reason.MEMORY, (outcome.reason, outcome.detail, outcome.stderr_tail[-500:])


def test_empty_files_in_tmp_count_to_the_runs_memory(course):
    """An empty file costs a tmpfs no bytes but costs the kernel an inode and a name."""
    body = """\
        os.chdir("/tmp")
        for n in range(400_000):
            os.close(os.open(f"f{n}", os.O_CREAT | os.O_WRONLY, 0o600))
        print("MADE them all", file=sys.stderr)
        write_png(output)
        """
    outcome = run(course, body, Limits(memory_bytes=128 * MIB, wall_seconds=60.0))
    assert outcome.reason is Reason.MEMORY, (outcome.reason, outcome.detail, outcome.stderr_tail[-500:])


def test_files_in_the_tmpfs_folders_count_to_the_runs_memory(course):
    """Each tmpfs folder is held by its own size (the output limit); together, and with the run's pages, they
    are held by its memory limit too (as a cgroup counts them)."""
    body = """\
        for place in ("/tmp", "/dev/shm"):
            with open(f"{place}/block", "wb") as f:
                for _ in range(90):
                    f.write(b"x" * (1 << 20))
        print("WROTE both", file=sys.stderr)
        time.sleep(3)
        write_png(output)
        """
    limits = Limits(memory_bytes=128 * MIB, output_bytes=100 * MIB, wall_seconds=60.0)
    outcome = run(course, body, limits)
    assert outcome.reason is Reason.MEMORY, (outcome.reason, outcome.detail, outcome.stderr_tail[-500:])


def test_each_process_holds_at_most_its_open_files(course):
    body = """\
        import resource
        print("LIMIT", *resource.getrlimit(resource.RLIMIT_NOFILE), file=sys.stderr)
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (4096, 4096))
        except (ValueError, OSError):
            print("CANNOT raise it", file=sys.stderr)
        write_png(output)
        """
    outcome = run(course, body, Limits(wall_seconds=30.0))
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    assert f"LIMIT {OPEN_FILES} {OPEN_FILES}" in outcome.stderr_tail and "CANNOT raise it" in outcome.stderr_tail


#: a process of 20,000 mappings (alternate pages of one made read-only: no page touched), and three children
#: forked from it, each a copy of all of them
MAPPERS = """\
    import ctypes
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mmap.restype = ctypes.c_void_p
    libc.mmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_long]
    base = libc.mmap(None, 20_000 * 4096, 3, 0x22, -1, 0)
    for i in range(0, 20_000, 2):
        libc.mprotect(ctypes.c_void_p(base + i * 4096), 4096, 1)
    kids = []
    for _ in range(3):
        pid = os.fork()
        if pid == 0:
            time.sleep(10)
            os._exit(0)
        kids.append(pid)
    print("MAPPED", sum(1 for _ in open("/proc/self/maps")), file=sys.stderr, flush=True)
    time.sleep(5)
    write_png(output)
    for pid in kids:
        os.kill(pid, 9)
        os.waitpid(pid, 0)
    """


def test_mappings_count_to_the_runs_memory(course):
    """Each mapping is the kernel's memory in no page of the process's: four processes of 20,000 mappings each
    (their pages a few MiB) are over a 128 MiB limit with what the kernel holds for their mappings."""
    outcome = run(course, MAPPERS, Limits(memory_bytes=128 * MIB, wall_seconds=30.0))
    assert outcome.reason is Reason.MEMORY, (outcome.reason, outcome.detail, outcome.stderr_tail[-500:])


def test_a_walk_counts_each_processes_mappings(monkeypatch):
    """A process whose address space could hold more mappings than the limit allows is counted by its own: under
    the limit with 1,000 (its pages and each mapping's cost), over it with 100,000."""
    mappings = {1: 1_000}
    monkeypatch.setattr(usage, "_cheap", lambda pid: (10 * MIB, MIB, (1 << 30) // usage.PAGE))
    monkeypatch.setattr(usage, "_share", lambda pid, resident: resident)
    monkeypatch.setattr(usage, "_mappings", lambda pid: mappings[pid])
    cost = usage.mapping_bytes(64)
    assert Shares(mapping=cost).pages([1], 64 * MIB) == (11 * MIB + 1_000 * cost, True)
    mappings[1] = 100_000
    pages, exact = Shares(mapping=cost).pages([1], 64 * MIB)
    assert exact and pages == 11 * MIB + 100_000 * cost > 64 * MIB


class _Clock:
    """A clock that a walk of page tables moves on (by ``walk`` seconds a process), and the watchdog's looks."""

    def __init__(self, walk: float):
        self.now, self.walk, self.walked = 0.0, walk, 0.0

    def __call__(self) -> float:
        return self.now


def test_walks_of_page_tables_take_at_most_their_fraction_of_the_time(monkeypatch):
    """Processes whose resident pages are over the limit (they share them) make every look need a walk of their
    page tables, as slow as the run makes it: the watchdog walks at most FRACTION of the time, and a walk
    whose sum is over the limit is what kills."""
    clock = _Clock(walk=0.05)
    pids = list(range(1000, 1010))

    def share(pid: int, resident: int) -> int:
        clock.now += clock.walk
        clock.walked += clock.walk
        return resident // 10  # (each process's share of the pages the ten of them share)

    monkeypatch.setattr(usage, "_cheap", lambda pid: (100 * MIB, 0, 0))
    monkeypatch.setattr(usage, "_share", share)
    monkeypatch.setattr(usage, "_mappings", lambda pid: 0)
    shares = Shares(clock, cpu=clock)  # (a walk's time all the watchdog's own CPU's)
    exact = []
    for _ in range(200):  # (20 s of looks, every tenth of a second)
        pages, fresh = shares.pages(pids, 500 * MIB)
        exact.append(fresh)
        assert pages == 100 * MIB or not fresh  # (a walk's sum: the tenth of 10 x 100 MiB)
        clock.now += 0.1
    assert clock.walked <= FRACTION * clock.now + len(pids) * clock.walk
    assert sum(exact) >= clock.now / (REFRESH + len(pids) * clock.walk / FRACTION) - 1  # (walks kept being made)


def test_a_look_at_a_real_family_sees_its_files_and_cpu(tmp_path):
    """Outside any sandbox (the watchdog's own reading of /proc): a child holding 50 files open and spinning."""
    child = subprocess.Popen(
        [
            "python3",
            "-c",
            "import os, time\nfds = [os.open('/dev/null', os.O_RDONLY) for _ in range(50)]\n"
            "t = time.process_time()\nwhile time.process_time() - t < 0.5: pass\ntime.sleep(60)",
        ],
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 30
        found = usage.family(child.pid, usage=True)
        while found.cpu_seconds < 0.4 and time.monotonic() < deadline:
            time.sleep(0.05)
            found = usage.family(child.pid, usage=True)
        assert list(found.threads) == [child.pid] and found.cpu_seconds >= 0.4
        assert usage.open_files([child.pid]) >= 53
    finally:
        os.killpg(child.pid, 9)
        child.wait()


def test_a_process_that_ends_during_a_walk_counts_nothing(monkeypatch):
    """Children that shared their parent's 300 MiB end while the watchdog walks: one read as resident before
    its walk has no rollup by then (nor resident pages), and counts nothing, not its pages of before."""
    statuses = {1: [300], 2: [300], 3: [300, 0]}  # (3's status read twice: before the walk, then ended)

    def read(path: str) -> str:
        pid = int(path.split("/")[2])
        if path.endswith("/status"):
            mib = statuses[pid].pop(0) if len(statuses[pid]) > 1 else statuses[pid][0]
            return f"RssAnon:\t{mib << 10} kB\n" if mib else ""
        return "" if pid == 3 else "Pss_Anon:\t102400 kB\nPss_Shmem:\t0 kB\n"

    monkeypatch.setattr(usage, "read", read)
    monkeypatch.setattr(usage, "_mappings", lambda pid: 0)
    pages, exact = Shares().pages([1, 2, 3], 512 * MIB)
    assert exact and pages == 200 * MIB


def test_a_walk_a_busy_machine_slows_owes_only_its_cpu_time(monkeypatch):
    """Four processes over the limit by their resident pages, walked while the machine is busy: each walk takes
    0.5 s of wall time but 1 ms of the watchdog's CPU, so the next look walks again, a tenth of a second on, and
    the walk that finds the run over its limit is not put off by the waits of the one before."""
    clock, cpu = _Clock(walk=0.5), _Clock(walk=0.001)
    over = {"now": False}

    def share(pid: int, resident: int) -> int:
        clock.now += clock.walk
        cpu.now += cpu.walk
        return resident if over["now"] else resident // 2

    monkeypatch.setattr(usage, "_cheap", lambda pid: (140 * MIB, 0, 0))
    monkeypatch.setattr(usage, "_share", share)
    monkeypatch.setattr(usage, "_mappings", lambda pid: 0)
    shares = Shares(clock, cpu=cpu)
    assert shares.pages([1, 2, 3, 4], 512 * MIB) == (280 * MIB, True)  # (mid-fork: half of it shared)
    over["now"] = True
    clock.now += 0.1
    assert shares.pages([1, 2, 3, 4], 512 * MIB) == (560 * MIB, True)


def test_a_last_look_walks_whatever_is_owed(monkeypatch):
    """A run's last look (at its wall time) walks its pages even when the walks' budget is spent."""
    clock = _Clock(walk=1.0)

    def share(pid: int, resident: int) -> int:
        clock.now += clock.walk
        return resident

    monkeypatch.setattr(usage, "_cheap", lambda pid: (300 * MIB, 0, 0))
    monkeypatch.setattr(usage, "_share", share)
    monkeypatch.setattr(usage, "_mappings", lambda pid: 0)
    shares = Shares(clock, cpu=clock)
    assert shares.pages([1, 2], 512 * MIB) == (600 * MIB, True)  # (a walk of 2 s: 8 s owed)
    clock.now += 0.1
    assert shares.pages([1, 2], 512 * MIB) == (600 * MIB, False)  # (the estimate)
    assert shares.pages([1, 2], 512 * MIB, walk=True) == (600 * MIB, True)


def test_a_process_still_in_the_machines_root_holds_no_sandbox_folders():
    """bubblewrap names the sandbox's first process as soon as it is cloned, before it has its own root: a look
    then saw the machine's /tmp (gigabytes of a disk's used blocks) as the run's tmpfs, and a busy machine's
    first look ended a run of a few bytes as out of memory.  A process whose root is the machine's holds none."""
    assert usage.folders(os.getpid()) == 0
    assert usage.folders(None) == 0
